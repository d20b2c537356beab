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

/// `FkModel::speed_bounds`: along straight joint-space segments, no point of the ball travels
/// farther than `Σ |Δq_v| · w_v` (path length over 400 sub-steps, every computed link of ARMAR
/// and Justin, random balls, segments up to the whole joint range).
#[test]
fn speed_bounds_bound_the_travel_of_every_point() {
    use manyhands::kinematics::{FkModel, Frame};
    use nalgebra::Vector3;
    use rand::Rng;

    let lib = library();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (mut bounded, mut tight) = (0usize, 0usize);
    for name in ["armar", "justin"] {
        let robot = lib.get(name).expect("robot").clone();
        let fk = FkModel::reduced(&robot);
        let vars: Vec<usize> = (0..robot.dof()).collect();
        let mut frames = vec![Frame::identity(); robot.links.len()];
        for _ in 0..300 {
            let mut a = vec![0.0; robot.dof()];
            robot.sample_vars(&vars, &mut a, &mut rng);
            let mut b = a.clone();
            // Short and long segments (a whole new sample).
            let scale: f64 = if rng.random::<bool>() { 0.05 } else { 1.0 };
            let mut far = vec![0.0; robot.dof()];
            robot.sample_vars(&vars, &mut far, &mut rng);
            for v in 0..robot.dof() {
                b[v] = a[v] + (far[v] - a[v]) * scale;
            }
            let link = fk.mount(rng.random_range(0..robot.links.len())).0;
            let centre = Vector3::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
            );
            let radius = rng.random_range(0.0..0.2);
            let Some(bounds) = fk.speed_bounds(&robot, link, &centre, radius) else {
                continue;
            };
            bounded += 1;
            let bound: f64 = bounds.iter().map(|&(v, w)| (b[v] - a[v]).abs() * w).sum();
            let dir = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let p = centre + dir * radius;
            let mut q = a.clone();
            let mut travel = 0.0;
            let mut last: Option<Vector3<f64>> = None;
            for k in 0..=400 {
                let t = k as f64 / 400.0;
                for v in 0..robot.dof() {
                    q[v] = a[v] + (b[v] - a[v]) * t;
                }
                fk.compute(&Frame::identity(), &q, &mut frames);
                let w = frames[link].transform_point(&p);
                if let Some(l) = last {
                    travel += (w - l).norm();
                }
                last = Some(w);
            }
            assert!(
                travel <= bound * (1.0 + 1e-9) + 1e-12,
                "{name} link {link}: travel {travel} > bound {bound}"
            );
            if travel > 0.3 * bound {
                tight += 1;
            }
        }
    }
    // The bounds are not vacuous: often within a factor of three of the travel.
    assert!(
        bounded > 400 && tight > 50,
        "{bounded} bounded, {tight} tight"
    );
}

/// Segments near an obstacle: from a free state toward a colliding one, bisected to just before
/// the contact, then a straight segment through that point in a random direction — they touch
/// for a few states or pass by.
fn grazing_segments(
    checker: &mut FastChecker,
    world: &CollisionWorld,
    start: &[f64],
    active: &[usize],
    count: usize,
    seed: u64,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    use rand::Rng;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let restrict = |q: &mut Vec<f64>| {
        for (i, v) in q.iter_mut().enumerate() {
            if !active.contains(&i) {
                *v = start[i];
            }
        }
    };
    while out.len() < count {
        let mut free = random_config_near(world, start, 0.3, 0.8, &mut rng);
        let mut hit = random_config_near(world, start, 0.3, 0.8, &mut rng);
        restrict(&mut free);
        restrict(&mut hit);
        if !checker.is_free(&free) || checker.is_free(&hit) {
            continue;
        }
        let mut mid = free.clone();
        for _ in 0..40 {
            for i in 0..mid.len() {
                mid[i] = 0.5 * (free[i] + hit[i]);
            }
            if checker.is_free(&mid) {
                free.clone_from(&mid);
            } else {
                hit.clone_from(&mid);
            }
        }
        let len: f64 = rng.random_range(0.05..0.6);
        let (mut a, mut b) = (free.clone(), free.clone());
        for &v in active {
            let d: f64 = rng.random_range(-1.0..1.0) * len;
            let back: f64 = rng.random_range(0.0..1.0);
            a[v] = free[v] - d * back;
            b[v] = free[v] + d * (1.0 - back);
        }
        out.push((a, b));
    }
    out
}

/// The fast checker's own segment check (`segment_free_skipping`, what planners use) gives
/// exactly the verdict of checking every state at the resolution, on random and grazing
/// segments of ARMAR's arm and hip in the kitchen (hand at the wok and the counter) — and checks
/// fewer states.
#[test]
fn skipping_segment_check_agrees_with_checking_every_state() {
    use manyhands::collision::FastModelSettings;
    use rand::Rng;

    let lib = library();
    for (name, group) in [
        ("kitchen", "torso_right_arm"),
        ("obstacle", "both_arms"),
        ("kitchen", "whole_body"),
    ] {
        let s = scene(name, &lib);
        let world = CollisionWorld::from_scene(&s);
        let start = CollisionWorld::start_config(&s);
        let Some(active) = world.robots[0]
            .robot
            .group(group)
            .map(|_| group_world_vars(&world, group))
        else {
            continue;
        };
        let settings = FastModelSettings::default();
        let mut skipping = FastChecker::for_active(&world, settings, &active, &start);
        let mut plain = FastChecker::for_active(&world, settings, &active, &start);
        let mv = MotionValidator::new(&world, plain.clone(), 0.5f64.to_radians(), 0.005);
        let mut segs = grazing_segments(&mut plain, &world, &start, &active, 1500, 3);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for k in 0..800 {
            let q = random_config_near(&world, &start, 0.3, 0.8, &mut rng);
            let mut a = start.clone();
            for &v in &active {
                a[v] = q[v];
            }
            let mut b = a.clone();
            let reach = if k % 2 == 0 { 0.8 } else { 0.2 };
            for &v in &active {
                b[v] += rng.random_range(-reach..reach);
            }
            segs.push((a, b));
        }
        let (mut same_free, mut same_hit, mut few, mut skipped) = (0, 0, 0, 0);
        let (mut plain_checks, mut skip_checks) = (0u64, 0u64);
        for (a, b) in &segs {
            let n = mv.steps(a, b);
            let c0 = skipping.checks();
            let Some(verdict) = skipping.segment_free_skipping(a, b, n, 0.06) else {
                continue;
            };
            skip_checks += skipping.checks() - c0;
            skipped += 1;
            let mut colliding = 0;
            let mut q = a.clone();
            for k in 1..=n {
                let t = k as f64 / n as f64;
                for i in 0..q.len() {
                    q[i] = a[i] + (b[i] - a[i]) * t;
                }
                if !plain.is_free(&q) {
                    colliding += 1;
                }
            }
            plain_checks += n as u64;
            assert_eq!(
                verdict,
                colliding == 0,
                "{name}: {colliding} of {n} states collide; a = {a:?}, b = {b:?}"
            );
            match colliding {
                0 => same_free += 1,
                1..=3 => {
                    few += 1;
                    same_hit += 1
                }
                _ => same_hit += 1,
            }
        }
        assert!(
            skipped > 900 && same_free > 100 && same_hit > 500 && few > 30,
            "{name} {group}: {skipped} segments, {same_free} free, {same_hit} colliding ({few} in ≤ 3 states)"
        );
        assert!(
            skip_checks < plain_checks / 2,
            "{name} {group}: {skip_checks} checks skipping, {plain_checks} states"
        );
    }
}

/// Where the speed bound is exact (one prismatic joint: the tool moves exactly `|Δx|`), the
/// skipping check still gives the verdict of every state: a thin wall anywhere along the
/// motion, hit by one state or by none, is found — a run end within half a run of it must be
/// tight. (Halving the inflation misses walls in the middle of runs.)
#[test]
fn skipping_finds_a_thin_wall_where_the_speed_bound_is_exact() {
    use manyhands::collision::{StaticBody, StaticKind};
    use manyhands::geometry::{iso_from_rpy, Geometry, Pose, Shape};
    use manyhands::model::Robot;
    use nalgebra::Vector3;
    use rand::Rng;
    use std::sync::Arc;

    let urdf = r#"<robot name="slider">
  <link name="world"/>
  <link name="tool"><collision><geometry><sphere radius="0.0005"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="world"/><child link="tool"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
</robot>"#;
    let robot = Arc::new(Robot::from_strings(urdf, None, std::path::Path::new(".")).unwrap());
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let (mut hit, mut free) = (0, 0);
    for _ in 0..400 {
        let x0: f64 = rng.random_range(0.05..0.95);
        let y0: f64 = if rng.random::<f64>() < 0.2 { 0.01 } else { 0.0 };
        let mut world = CollisionWorld::single(robot.clone(), Pose::identity());
        world.statics = vec![StaticBody {
            name: "wall".into(),
            kind: StaticKind::Obstacle,
            pose: iso_from_rpy([x0, y0, 0.0], [0.0; 3]),
            shapes: vec![Geometry {
                origin: Pose::identity(),
                shape: Shape::Box {
                    half_extents: Vector3::new(0.0005, 0.005, 0.005),
                },
            }],
        }];
        let mut skipping = FastChecker::new(&world);
        let mut plain = FastChecker::new(&world);
        let (a, b, n) = ([0.0], [1.0], 200);
        let verdict = skipping
            .segment_free_skipping(&a, &b, n, 0.06)
            .expect("a 1 m motion at 5 mm skips");
        let every = (1..=n).all(|k| plain.is_free(&[k as f64 / n as f64]));
        assert_eq!(verdict, every, "wall at x = {x0}, y = {y0}");
        if every {
            free += 1;
        } else {
            hit += 1;
        }
        assert!(skipping.checks() < n as u64 / 2 || !every);
    }
    assert!(hit > 50 && free > 150, "{hit} hit, {free} free");
}
