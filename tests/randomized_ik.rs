//! Randomized whole-body IK (paper 000 §II-A/D, §III): answers reach their grasps (FK to 1e-6)
//! and are collision-free under the exact checker; unreachable targets fail fast with
//! "no solution after N tries".

use std::path::Path;
use std::sync::{Arc, OnceLock};

use manyhands::collision::{CollisionChecker, CollisionWorld, ExactChecker};
use manyhands::geometry::Pose;
use manyhands::kinematics::dual_arm::DualArmSolution;
use manyhands::kinematics::randomized::{
    gradient_ascent, IkSolution, RandomizedIkError, RandomizedIkSettings,
};
use manyhands::kinematics::{link_pose, Chain};
use manyhands::model::{load_robot_dir, RobotLibrary};
use manyhands::reachability::queries::{DualArmProblem, SingleArmProblem};
use manyhands::reachability::{GridParams, ObjectPlacement, ReachabilityGrid};
use manyhands::Scene;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn lib() -> RobotLibrary {
    load_robot_dir(&Path::new(env!("CARGO_MANIFEST_DIR")).join("robots")).expect("robots load")
}

fn scene(name: &str) -> Scene {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.json"));
    Scene::from_file(&p, &lib()).expect("scene loads")
}

/// Right-arm grid shared by the tests (built once, 600k samples).
fn right_grid() -> Arc<ReachabilityGrid> {
    static G: OnceLock<Arc<ReachabilityGrid>> = OnceLock::new();
    G.get_or_init(|| {
        let lib = lib();
        let robot = lib.get("armar").expect("armar").clone();
        let chain = Chain::from_group(&robot, "right_arm").expect("chain");
        let p = GridParams::auto(&robot, &chain, 0.05, 8, 600_000, 3).expect("params");
        Arc::new(ReachabilityGrid::build(&robot, "right_arm", &p, &|_| {}).expect("build"))
    })
    .clone()
}

/// FK of `link` in the world for robot configuration `q`.
fn world_link(base: &Pose, robot: &manyhands::Robot, q: &[f64], link: &str) -> Pose {
    base * link_pose(robot, q, robot.link(link).expect("link"))
}

fn pose_err(a: &Pose, b: &Pose) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm(),
        a.rotation.angle_to(&b.rotation),
    )
}

/// Every answer: FK reaches the grasp within 1e-6, joints within limits, exact checker free.
fn check_single(prob: &SingleArmProblem, object: &Pose, sol: &IkSolution) {
    let robot = prob.ik.robot();
    let target = object * prob.grasps.tcps[sol.grasp];
    let tcp = world_link(&prob.robot_base, robot, &sol.config, "right_tcp");
    let (ep, er) = pose_err(&tcp, &target);
    assert!(
        ep < 1e-6 && er < 1e-6,
        "grasp {} missed by {ep:.2e} m / {er:.2e} rad",
        sol.grasp
    );
    robot.check_config(&sol.config).expect("within limits");
    // Joints outside the chain are untouched.
    for v in 0..robot.dof() {
        if !prob.ik.split().chain.vars.contains(&v) {
            assert_eq!(sol.config[v], prob.start[v]);
        }
    }
    let world = prob.checkers.world(sol.grasp).expect("world");
    let mut exact = ExactChecker::new(world);
    let wq = prob.checkers.world_config(&sol.config);
    assert!(
        exact.is_free(&wq),
        "exact checker: {:?}",
        exact.first_contact(&wq)
    );
}

#[test]
fn single_arm_answers_reach_their_grasps_and_are_collision_free() {
    for (name, drop_box) in [("kitchen", false), ("obstacle", false), ("obstacle", true)] {
        let mut sc = scene(name);
        if drop_box {
            sc.obstacles.retain(|b| b.name != "obstacle");
        }
        let mut prob =
            SingleArmProblem::new(&sc, "armar", "torso_right_arm", "wok").expect("problem");
        assert_eq!(prob.grasps.tcps.len(), 15);
        assert_eq!(prob.ik.split().free_vars.len(), 3);
        prob.set_grid(Some(right_grid())).expect("grid");
        // The wok of `obstacle` touches the box at its scene pose: move it right until it is free.
        let mut place = ObjectPlacement::new(&CollisionWorld::from_scene(&sc), "wok").expect("wok");
        let mut object = prob.object_pose;
        while !place.is_free(&object) {
            object.translation.y -= 0.02;
        }
        let settings = RandomizedIkSettings::default();
        let mut solved = 0;
        for use_grid in [false, true] {
            for seed in 0..8 {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let sol = prob
                    .solve(&object, use_grid, &settings, &mut rng)
                    .expect("solved");
                assert!(sol.counters.ik_calls >= 1 && sol.counters.collision_checks >= 1);
                assert!(sol.counters.tries <= settings.max_tries);
                if use_grid {
                    assert!(sol.counters.reach_lookups > 0);
                }
                check_single(&prob, &object, &sol);
                // Same seed, same answer.
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let again = prob
                    .solve(&object, use_grid, &settings, &mut rng)
                    .expect("solved");
                assert_eq!(again, sol);
                solved += 1;
            }
        }
        assert_eq!(solved, 16, "{name}");
    }
}

#[test]
fn reachability_cuts_analytic_ik_calls() {
    let sc = scene("kitchen");
    let mut prob = SingleArmProblem::new(&sc, "armar", "torso_right_arm", "wok").expect("problem");
    prob.set_grid(Some(right_grid())).expect("grid");
    let object = prob.object_pose;
    let settings = RandomizedIkSettings::default();
    let mut calls = [0u64; 2];
    for (k, use_grid) in [false, true].into_iter().enumerate() {
        for seed in 0..40 {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
            calls[k] += prob
                .solve(&object, use_grid, &settings, &mut rng)
                .expect("solved")
                .counters
                .ik_calls;
        }
    }
    assert!(
        calls[0] > 4 * calls[1],
        "without {} with {}",
        calls[0],
        calls[1]
    );
}

#[test]
fn unreachable_target_fails_fast_with_no_solution() {
    let sc = scene("kitchen");
    let mut prob = SingleArmProblem::new(&sc, "armar", "torso_right_arm", "wok").expect("problem");
    prob.set_grid(Some(right_grid())).expect("grid");
    let far = Pose::translation(3.0, -1.0, 2.5);
    let settings = RandomizedIkSettings {
        max_tries: 3000,
        ..Default::default()
    };
    for use_grid in [false, true] {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let t = std::time::Instant::now();
        let e = prob
            .solve(&far, use_grid, &settings, &mut rng)
            .expect_err("unreachable");
        assert!(t.elapsed().as_secs_f64() < 2.0, "took {:?}", t.elapsed());
        assert!(
            matches!(e, RandomizedIkError::NoSolution { tries: 3000, .. }),
            "{e}"
        );
        assert!(
            e.to_string().starts_with("no solution after 3000 tries"),
            "{e}"
        );
    }
    // Malformed input: errors, not panics.
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let nan = Pose::translation(f64::NAN, 0.0, 1.0);
    let e = prob
        .solve(&nan, true, &settings, &mut rng)
        .expect_err("nan");
    assert!(matches!(e, RandomizedIkError::BadTarget));
}

fn check_dual(prob: &DualArmProblem, sol: &DualArmSolution) {
    let robot = prob.ik.robot();
    let obj = sol.object_pose;
    for (link, g) in [
        ("left_tcp", prob.left_grasps.tcps[sol.left_grasp]),
        ("right_tcp", prob.right_grasps.tcps[sol.right_grasp]),
    ] {
        let (ep, er) = pose_err(
            &world_link(&prob.robot_base, robot, &sol.config, link),
            &(obj * g),
        );
        assert!(
            ep < 1e-6 && er < 1e-6,
            "{link} missed by {ep:.2e} m / {er:.2e} rad"
        );
    }
    robot.check_config(&sol.config).expect("within limits");
    let world = prob.checkers.world(sol.left_grasp).expect("world");
    let mut exact = ExactChecker::new(world);
    let wq = prob.checkers.world_config(&sol.config);
    assert!(
        exact.is_free(&wq),
        "exact checker: {:?}",
        exact.first_contact(&wq)
    );
}

#[test]
fn dual_arm_answers_hold_the_object_with_both_hands() {
    let sc = scene("obstacle");
    let mut prob = DualArmProblem::new(&sc, "armar", "torso_left_arm", "torso_right_arm", "wok")
        .expect("problem");
    let lib = lib();
    let robot = lib.get("armar").expect("armar").clone();
    let chain = Chain::from_group(&robot, "left_arm").expect("chain");
    let p = GridParams::auto(&robot, &chain, 0.05, 8, 600_000, 4).expect("params");
    let left = Arc::new(ReachabilityGrid::build(&robot, "left_arm", &p, &|_| {}).expect("build"));
    // Grids of the wrong side are refused.
    assert!(prob.set_grids(Some((right_grid(), left.clone()))).is_err());
    prob.set_grids(Some((left, right_grid()))).expect("grids");
    let region = ([0.3, -0.3, 1.0], [0.6, 0.2, 1.4]);
    let settings = RandomizedIkSettings::default();
    for held in [None, Some(2)] {
        for use_grids in [true] {
            for seed in 0..4 {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let sol = prob
                    .solve(region, held, use_grids, &settings, &mut rng)
                    .unwrap_or_else(|e| panic!("held {held:?} grids {use_grids}: {e}"));
                if let Some(h) = held {
                    assert_eq!(sol.left_grasp, h);
                }
                let t = sol.object_pose.translation.vector;
                if sol.counters.gradient_steps == 0 {
                    assert!((0..3).all(|k| t[k] >= region.0[k] && t[k] <= region.1[k]));
                }
                check_dual(&prob, &sol);
            }
        }
    }
}

#[test]
fn gradient_ascent_climbs_to_a_local_maximum() {
    // Score peaked at (0.5, 0.2, 1.0), yaw 0.3; the ascent must increase it monotonically and
    // stop within a voxel of the peak; a forbidden half-space (x > 0.45) stops it earlier.
    let peak = Pose::from_parts(
        nalgebra::Translation3::new(0.5, 0.2, 1.0),
        nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
    );
    let score = |p: &Pose| {
        let (ep, er) = pose_err(p, &peak);
        (-(ep * ep) * 20.0 - er * er).exp()
    };
    let steps = [0.05, 0.05, 0.05, 0.2, 0.2, 0.2];
    let start = Pose::translation(0.1, -0.1, 1.2);
    let mut last = score(&start);
    let (end, s, moves) = gradient_ascent(&start, &steps, 100, |p, _| score(p), |_| true);
    assert!(moves > 5 && s > last);
    let (ep, er) = pose_err(&end, &peak);
    assert!(ep < 0.05 && er < 0.2, "{ep} {er}");
    let mut seen = Vec::new();
    let (end2, s2, _) = gradient_ascent(
        &start,
        &steps,
        100,
        |p, _| {
            let v = score(p);
            seen.push(v);
            v
        },
        |p| p.translation.x <= 0.45,
    );
    assert!(end2.translation.x <= 0.45 && s2 < s && s2 > last);
    last = s2;
    assert!(last > 0.0);
    // A score cut short below the floor (here: −∞ for every neighbour that is not better)
    // leads to the same climb.
    let (end3, s3, moves3) = gradient_ascent(
        &start,
        &steps,
        100,
        |p, floor| {
            let v = score(p);
            if v <= floor {
                f64::NEG_INFINITY
            } else {
                v
            }
        },
        |_| true,
    );
    assert_eq!((end3, s3, moves3), (end, s, moves));
    // max_steps bounds the moves.
    let (_, _, m) = gradient_ascent(&start, &steps, 3, |p, _| score(p), |_| true);
    assert_eq!(m, 3);
}

/// A platform-frame grid (10 cm, 8 angle bins) of chain group `group`.
fn platform_grid(
    robot: &Arc<manyhands::Robot>,
    group: &str,
    samples: u64,
    seed: u64,
) -> ReachabilityGrid {
    let chain = Chain::from_group(robot, group).expect("chain");
    let p = GridParams::auto(robot, &chain, 0.1, 8, samples, seed).expect("params");
    ReachabilityGrid::build(robot, group, &p, &|_| {}).expect("build")
}

#[test]
fn base_placement_dual_arm_ik_on_the_kitchen_wok() {
    use manyhands::collision::{BodyId, FastChecker};
    use manyhands::kinematics::dual_arm::DualArmIk;
    use manyhands::reachability::inverse::{bimanual, ik_dual_arm, inverse_map, placement_cdf};
    use manyhands::reachability::{hand_links, queries::grasp_set};

    let sc = scene("kitchen");
    let robot = sc.robots[0].robot.clone();
    let base = sc.robots[0].base_pose;
    let start = sc.robots[0].start_config();
    let grid = |group: &str| platform_grid(&robot, group, 400_000, 11);
    let (gl, gr) = (grid("torso_left_arm"), grid("torso_right_arm"));
    let wok = sc.object("wok").expect("wok").body.pose;
    let lg = grasp_set(&sc, "wok", "left_hand").expect("left");
    let rg = grasp_set(&sc, "wok", "right_hand").expect("right");
    let tl: Vec<Pose> = lg.tcps.iter().map(|g| wok * g).collect();
    let tr: Vec<Pose> = rg.tcps.iter().map(|g| wok * g).collect();
    let bv = ["base_x", "base_y", "base_yaw"].map(|n| robot.var(n).expect("base var"));
    let c = [wok.translation.x, wok.translation.y];
    let ml = inverse_map(&robot, &base, &start, &bv, &gl, &tl, c, 0.1, 1.2, 16, 0.0).expect("map");
    let mr = inverse_map(&robot, &base, &start, &bv, &gr, &tr, c, 0.1, 1.2, 16, 0.0).expect("map");
    let (bi, rights) = bimanual(&ml, &mr).expect("same layout");
    let cdf = placement_cdf(&bi);
    assert!(bi.max() > 0.0);
    for (k, right) in rights.iter().enumerate() {
        assert!(bi.value[k] <= ml.value[k] && bi.value[k] <= mr.value[k]);
        assert_eq!(
            bi.value[k] > 0.0,
            !bi.grasps[k].is_empty() && !right.is_empty()
        );
    }
    // Collision world: the wok stays on the counter, both hands may touch it.
    let mut world = CollisionWorld::from_scene(&sc);
    let wi = world
        .statics
        .iter()
        .position(|s| s.name == "wok")
        .expect("wok");
    let mut hands = hand_links(&robot, "left_hand").expect("hand");
    hands.extend(hand_links(&robot, "right_hand").expect("hand"));
    for &l in &hands {
        world.allow(BodyId::Link { robot: 0, link: l }, BodyId::Static(wi));
    }
    let mut fast = FastChecker::new(&world);
    let mut exact = ExactChecker::new(&world);
    let ik = DualArmIk::new(robot.clone(), "torso_left_arm", "torso_right_arm").expect("ik");
    let settings = RandomizedIkSettings::default();
    for seed in 0..4 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let sol = ik_dual_arm(
            &ik,
            &base,
            &start,
            &bv,
            &bi,
            &cdf,
            &rights,
            &tl,
            &tr,
            &settings,
            &mut rng,
            |q| fast.is_free(q),
        )
        .expect("base placement found");
        for (link, t) in [
            ("left_tcp", tl[sol.left_grasp]),
            ("right_tcp", tr[sol.right_grasp]),
        ] {
            let (ep, er) = pose_err(&world_link(&base, &robot, &sol.config, link), &t);
            assert!(ep < 1e-6 && er < 1e-6, "{link}: {ep:.2e} m {er:.2e} rad");
        }
        robot.check_config(&sol.config).expect("limits");
        assert!(
            exact.is_free(&sol.config),
            "{:?}",
            exact.first_contact(&sol.config)
        );
        // The base moved off the origin only as far as the map reaches.
        assert!(sol.config[bv[0]].abs() <= 5.0 && sol.config[bv[1]].abs() <= 5.0);
    }
}

/// The inverse reachability map (002 §III-A) equals plain lookups of every base pose and
/// grasp: skipping targets the grid cannot reach at any yaw (distance to the yaw axis, height)
/// and positions in empty voxels changes no value and no grasp list.
#[test]
fn inverse_map_equals_a_lookup_of_every_base_pose() {
    use manyhands::kinematics::randomized::ReachabilityMap;
    use manyhands::kinematics::FkPath;
    use manyhands::reachability::inverse::inverse_map;
    use manyhands::reachability::queries::grasp_set;

    let sc = scene("kitchen");
    let robot = sc.robots[0].robot.clone();
    let base = sc.robots[0].base_pose;
    let start = sc.robots[0].start_config();
    let grid = platform_grid(&robot, "torso_right_arm", 200_000, 5);
    let platform = robot.link(grid.base_link()).expect("platform");
    let path = FkPath::new(&robot, platform);
    let bv = ["base_x", "base_y", "base_yaw"].map(|n| robot.var(n).expect("base var"));
    // Lookups at zero (the skipped ones among them) and above zero must both be plentiful.
    let (mut zero, mut reached) = (0usize, 0usize);
    for (object, threshold) in [("wok", 0.0), ("table", 0.0), ("table", 0.3)] {
        let pose = sc.object(object).expect("object").body.pose;
        let set = grasp_set(&sc, object, "right_hand").expect("grasps");
        let targets: Vec<Pose> = set.tcps.iter().map(|g| pose * g).collect();
        let c = [pose.translation.x, pose.translation.y];
        let m = inverse_map(
            &robot, &base, &start, &bv, &grid, &targets, c, 0.1, 1.5, 16, threshold,
        )
        .expect("map");
        let mut q = start.clone();
        let mut probs = vec![0.0; targets.len()];
        for ix in 0..m.dims[0] {
            for iy in 0..m.dims[1] {
                for iw in 0..m.yaw_bins {
                    let (x, y, w) = m.cell_pose(ix, iy, iw);
                    q[bv[0]] = x;
                    q[bv[1]] = y;
                    q[bv[2]] = w;
                    let inv = (base * path.pose(&q)).inverse();
                    let mut value = 0.0f32;
                    let mut list = Vec::new();
                    for (g, t) in targets.iter().enumerate() {
                        probs[g] = grid.probability(&(inv * t));
                        if probs[g] > threshold {
                            value = value.max(probs[g] as f32);
                            list.push(g as u16);
                        }
                    }
                    // The batched lookup agrees with the single one.
                    let mut batch = vec![f64::NAN; targets.len()];
                    ReachabilityMap::probabilities(&grid, &inv, &targets, &mut batch);
                    assert_eq!(batch, probs);
                    let k = (ix * m.dims[1] + iy) * m.yaw_bins + iw;
                    assert_eq!(m.value[k], value, "{object}: cell ({ix}, {iy}) yaw {iw}");
                    assert_eq!(m.grasps[k], list, "{object}: cell ({ix}, {iy}) yaw {iw}");
                    let z = probs.iter().filter(|&&p| p == 0.0).count();
                    zero += z;
                    reached += probs.len() - z;
                }
            }
        }
        assert!(m.max() > 0.0, "{object}: some base pose reaches a grasp");
    }
    assert!(
        zero > 10_000 && reached > 1_000,
        "{zero} zero, {reached} reached"
    );
}
