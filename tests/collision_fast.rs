//! The fast checker against the exact one: never "free" where exact says collision, and "free"
//! wherever exact says free with a margin of at least the fast model's over-approximation.

use std::path::PathBuf;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use manyhands::collision::{
    random_boxes, random_config_near, CollisionChecker, CollisionWorld, ExactChecker, FastChecker,
    MotionValidator, RandomBoxes,
};
use manyhands::model::{load_robot_dir, RobotLibrary};
use manyhands::Scene;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn library() -> RobotLibrary {
    load_robot_dir(&root().join("robots")).unwrap()
}

fn scene(name: &str, lib: &RobotLibrary) -> Scene {
    Scene::from_file(&root().join(format!("scenes/{name}.json")), lib).unwrap()
}

/// World variables of SRDF group `group` of the world's first robot.
fn group_world_vars(world: &CollisionWorld, group: &str) -> Vec<usize> {
    let p = &world.robots[0];
    let g = p.robot.group(group).expect("group");
    g.vars.iter().map(|v| p.offset + v).collect()
}

/// Compares both checkers on `n` random configurations; returns (collisions, free-with-margin).
fn compare(scene: &Scene, world: &CollisionWorld, n: usize, seed: u64) -> (usize, usize) {
    let mut fast = FastChecker::new(world);
    let mut exact = ExactChecker::new(world);
    let margin = fast.max_overapproximation() + 1e-9;
    assert!(
        margin.is_finite() && margin < 0.1,
        "over-approximation {margin}"
    );
    let start = CollisionWorld::start_config(scene);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut hits, mut clear) = (0, 0);
    for k in 0..n {
        let q = random_config_near(world, &start, 0.3, 0.5, &mut rng);
        let f = fast.is_free(&q);
        if !exact.is_free(&q) {
            hits += 1;
            assert!(
                !f,
                "sample {k}: exact finds {:?} but fast says free; q = {q:?}",
                exact.first_contact(&q)
            );
        } else if exact.is_free_with_margin(&q, margin) {
            clear += 1;
            assert!(
                f,
                "sample {k}: exact is free by {margin} m but fast finds {:?}; q = {q:?}",
                fast.first_contact(&q)
            );
        }
    }
    assert_eq!(fast.checks(), n as u64);
    (hits, clear)
}

#[test]
fn fast_agrees_with_exact_on_100k_armar_configurations_in_kitchen() {
    let lib = library();
    let s = scene("kitchen", &lib);
    let world = CollisionWorld::from_scene(&s);
    let (hits, clear) = compare(&s, &world, 100_000, 7);
    // Both outcomes must be well represented, or the test proves little.
    assert!(
        hits > 20_000 && clear > 20_000,
        "collisions {hits}, free with margin {clear}"
    );
}

#[test]
fn fast_agrees_with_exact_among_random_boxes_and_two_robots_with_a_held_object() {
    let lib = library();
    let empty = scene("empty", &lib);
    let boxes = random_boxes(
        &empty,
        &RandomBoxes {
            count: 30,
            seed: 3,
            ..RandomBoxes::default()
        },
        &lib,
    )
    .unwrap();
    let world = CollisionWorld::from_scene(&boxes);
    let (hits, clear) = compare(&boxes, &world, 20_000, 11);
    assert!(hits > 1000 && clear > 1000, "{hits} {clear}");

    // Two robots; the wok held in armar_a's right hand.
    let s = scene("handoff", &lib);
    let mut world = CollisionWorld::from_scene(&s);
    let q0 = CollisionWorld::start_config(&s);
    let r = &world.robots[0].robot;
    let tcp = r.link("right_tcp").unwrap();
    let hand: Vec<usize> = r
        .group("right_hand")
        .map(|g| g.links.clone())
        .unwrap_or_default();
    let obj = s.objects[0].body.name.clone();
    world.attach(&obj, 0, tcp, &q0, hand).expect("attach");
    let (hits, clear) = compare(&s, &world, 20_000, 13);
    assert!(hits > 1000 && clear > 1000, "{hits} {clear}");
}

#[test]
fn random_boxes_are_seeded_and_leave_the_start_free() {
    let lib = library();
    let empty = scene("empty", &lib);
    let p = RandomBoxes {
        count: 30,
        seed: 5,
        ..RandomBoxes::default()
    };
    let a = random_boxes(&empty, &p, &lib).unwrap();
    let b = random_boxes(&empty, &p, &lib).unwrap();
    assert_eq!(a.json, b.json);
    assert_eq!(a.obstacles.len(), empty.obstacles.len() + 30);
    let c = random_boxes(&empty, &RandomBoxes { seed: 6, ..p }, &lib).unwrap();
    assert_ne!(a.json, c.json);
    let world = CollisionWorld::from_scene(&a);
    let q0 = CollisionWorld::start_config(&a);
    assert!(ExactChecker::new(&world).is_free(&q0));
}

#[test]
fn motion_validator_rejects_a_sweep_through_the_counter() {
    let lib = library();
    let s = scene("kitchen", &lib);
    let world = CollisionWorld::from_scene(&s);
    let q0 = CollisionWorld::start_config(&s);
    let mut exact = ExactChecker::new(&world);
    assert!(
        exact.is_free(&q0),
        "kitchen start must be free: {:?}",
        exact.first_contact(&q0)
    );
    let r = &world.robots[0].robot;
    // Drive the base forward until the platform is inside the counter, or a wall.
    let bx = r.var("base_x").unwrap();
    let by = r.var("base_y").unwrap();
    let mut far = None;
    for dir in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
        let mut q = q0.clone();
        q[bx] += 2.5 * dir.0;
        q[by] += 2.5 * dir.1;
        if !exact.is_free(&q) {
            far = Some(q);
            break;
        }
    }
    let far = far.expect("some direction hits furniture within 2.5 m");
    let mut mv = MotionValidator::new(&world, FastChecker::new(&world), 0.5f64.to_radians(), 0.005);
    assert!(!mv.is_valid(&q0, &far));
    let mut tiny = q0.clone();
    tiny[bx] += 0.001;
    assert!(mv.is_valid(&q0, &tiny) == exact.is_free(&tiny));
    assert_eq!(mv.steps(&q0, &far), 500);
}

/// Shipped scenes: robots start free, and no object rests inside an obstacle.
#[test]
fn shipped_scenes_start_free_and_objects_clear_of_obstacles() {
    let lib = library();
    for name in ["kitchen", "empty", "obstacle", "handoff"] {
        let s = scene(name, &lib);
        let q0 = CollisionWorld::start_config(&s);
        let world = CollisionWorld::from_scene(&s);
        let mut exact = ExactChecker::new(&world);
        assert!(exact.is_free(&q0), "{name}: {:?}", exact.first_contact(&q0));
        for o in &s.objects {
            // Hang the object on the first robot's root, every robot link allowed to touch it:
            // only object–obstacle pairs remain.
            let mut w = CollisionWorld::from_scene(&s);
            let links: Vec<usize> = (0..w.robots[0].robot.links.len()).collect();
            w.attach(&o.body.name, 0, 0, &q0, links).expect("attach");
            for other in 1..w.robots.len() {
                let n = w.robots[other].robot.links.len();
                for l in 0..n {
                    w.allow(
                        manyhands::collision::BodyId::Attached(0),
                        manyhands::collision::BodyId::Link {
                            robot: other,
                            link: l,
                        },
                    );
                }
            }
            let mut ex = ExactChecker::new(&w);
            assert!(
                ex.is_free(&q0),
                "{name}: object {} touches {:?}",
                o.body.name,
                ex.first_contact(&q0)
            );
        }
    }
}

/// A checker frozen to the active variables of a group ([`FastChecker::for_active`]) answers
/// exactly as the full checker: over many frozen configurations (some with the frozen part in
/// collision, so every state collides), with only the group moving, and after a move of a
/// frozen variable (the checker then rebuilds itself).
#[test]
fn checker_for_active_variables_agrees_with_the_full_checker() {
    let lib = library();
    for (name, group) in [("kitchen", "torso_right_arm"), ("handoff", "right_arm")] {
        let s = scene(name, &lib);
        let world = CollisionWorld::from_scene(&s);
        let start = CollisionWorld::start_config(&s);
        let active = group_world_vars(&world, group);
        let mut full = FastChecker::new(&world);
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let (mut hits, mut free, mut always) = (0, 0, 0);
        for _ in 0..150 {
            let q0 = random_config_near(&world, &start, 0.3, 0.5, &mut rng);
            let mut frozen = FastChecker::for_active(
                &world,
                manyhands::collision::FastModelSettings::default(),
                &active,
                &q0,
            );
            let mut n_hit = 0;
            for k in 0..100 {
                let mut q = random_config_near(&world, &start, 0.3, 0.5, &mut rng);
                if k != 99 {
                    // Only the group moves (the last sample moves everything).
                    for (i, v) in q.iter_mut().enumerate() {
                        if !active.contains(&i) {
                            *v = q0[i];
                        }
                    }
                }
                let f = full.is_free(&q);
                assert_eq!(frozen.is_free(&q), f, "{name}: q0 = {q0:?}, q = {q:?}");
                if f {
                    free += 1;
                } else {
                    hits += 1;
                    n_hit += 1;
                }
            }
            assert_eq!(frozen.checks(), 100);
            if n_hit == 100 {
                always += 1;
            }
        }
        assert!(
            hits > 1000 && free > 1000 && always > 0,
            "{name}: {hits} collisions, {free} free, {always} always colliding"
        );
    }
}

/// Pairs the checkers drop as out of reach (no configuration within the joint limits brings
/// them together) must never be the ones that collide: over the whole joint range of a group
/// (not only near the start), the frozen and the full fast checker report every collision the
/// exact checker finds.
#[test]
fn pairs_dropped_as_out_of_reach_never_collide() {
    let lib = library();
    for (name, group) in [
        ("kitchen", "torso_right_arm"),
        ("kitchen", "torso_left_arm"),
        ("handoff", "right_arm"),
    ] {
        let s = scene(name, &lib);
        let world = CollisionWorld::from_scene(&s);
        let start = CollisionWorld::start_config(&s);
        let p = &world.robots[0];
        let active = group_world_vars(&world, group);
        let mut frozen = FastChecker::for_active(
            &world,
            manyhands::collision::FastModelSettings::default(),
            &active,
            &start,
        );
        let mut full = FastChecker::new(&world);
        assert!(
            frozen.pair_count() < full.pair_count(),
            "{name}/{group}: pairs dropped"
        );
        let mut exact = ExactChecker::new(&world);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut hits = 0;
        for k in 0..20_000 {
            let mut q = start.clone();
            for &v in &active {
                q[v] = p.robot.var_limits(v - p.offset).sample(&mut rng);
            }
            if !exact.is_free(&q) {
                hits += 1;
                assert!(
                    !frozen.is_free(&q) && !full.is_free(&q),
                    "{name}/{group} sample {k}: exact finds {:?}, a fast checker says free",
                    exact.first_contact(&q)
                );
            }
        }
        assert!(hits > 2_000, "{name}/{group}: {hits} collisions");
    }
}
