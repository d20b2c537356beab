//! Certified motion checks of the fast checker ([`FastChecker::motion_certified`]) on grazing
//! segments of primitive robots: boxes, cylinders, capsules, spheres and meshes, an attached
//! object, two robots at once, and ARMAR in the kitchen (with and without the wok in its hand).
//! Each segment is made by bisecting from a free state toward a colliding one to the contact,
//! backing off by a little and passing through that point in a random direction. Every
//! certified segment must be free under a dense check (the exact parry checker at ≤ 0.002 rad /
//! 1 mm steps, and the fast model itself at a quarter of that); segments far from contact (free
//! with every moving body padded by 1 cm at those states) must be certified.

mod common;

use std::path::Path;
use std::sync::Arc;

use common::obstacle;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use manyhands::collision::{
    random_config_near, Certification, CollisionChecker, CollisionWorld, ExactChecker, FastChecker,
    FastModelSettings, StaticBody, StaticKind,
};
use manyhands::geometry::{iso_from_rpy, Geometry, Pose, Shape};
use manyhands::model::{load_robot_dir, JointKind, Robot, Scene};

/// A 4-joint arm whose links are a box, a cylinder, a capsule, a mesh (an OBJ written to `dir`)
/// and a sphere.
fn primitive_arm(dir: &Path) -> Arc<Robot> {
    std::fs::write(
        dir.join("wedge.obj"),
        "v 0 -0.04 -0.04\nv 0.25 -0.04 -0.04\nv 0 0.04 -0.04\nv 0 -0.04 0.04\nv 0.25 0.04 0.04\n\
         f 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 5\nf 2 4 5\nf 3 4 5\n",
    )
    .expect("write mesh");
    let joint = |name: &str, parent: &str, child: &str, xyz: &str, axis: &str| {
        format!(
            r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>
               <origin xyz="{xyz}"/><axis xyz="{axis}"/>
               <limit lower="-2.8" upper="2.8" velocity="1" effort="1"/></joint>"#
        )
    };
    let urdf = format!(
        r#"<robot name="prim">
  <link name="base"><collision><origin xyz="0 0 0.1"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0 0 0.2" rpy="0 0 0"/><geometry><cylinder radius="0.05" length="0.4"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0.2 0 0" rpy="0 1.5708 0"/><geometry><capsule radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="l3"><collision><geometry><mesh filename="wedge.obj"/></geometry></collision>
                  <collision><origin xyz="0.12 0 0.05"/><geometry><box size="0.1 0.03 0.06"/></geometry></collision></link>
  <link name="tip"><collision><origin xyz="0.05 0 0"/><geometry><sphere radius="0.03"/></geometry></collision></link>
  {}{}{}{}
</robot>"#,
        joint("j1", "base", "l1", "0 0 0.2", "0 0 1"),
        joint("j2", "l1", "l2", "0 0 0.4", "0 1 0"),
        joint("j3", "l2", "l3", "0.4 0 0", "0 1 0"),
        joint("j4", "l3", "tip", "0.25 0 0", "1 0 0"),
    );
    let srdf = r#"<robot name="prim">
  <disable_collisions link1="base" link2="l1" reason="Adjacent"/>
  <disable_collisions link1="l1" link2="l2" reason="Adjacent"/>
  <disable_collisions link1="l2" link2="l3" reason="Adjacent"/>
  <disable_collisions link1="l3" link2="tip" reason="Adjacent"/>
</robot>"#;
    Arc::new(Robot::from_strings(&urdf, Some(srdf), dir).expect("robot"))
}

/// Boxes and cylinders around the arm.
fn clutter() -> Vec<StaticBody> {
    let cuboid = |x: f64, y: f64, z: f64| Shape::Box {
        half_extents: Vector3::new(x, y, z),
    };
    vec![
        obstacle(
            "shelf",
            [0.45, 0.3, 0.45],
            [0.0, 0.0, 0.4],
            cuboid(0.2, 0.05, 0.02),
        ),
        obstacle("post", [0.3, -0.35, 0.4], [0.3, 0.0, 0.0], {
            Shape::Cylinder {
                radius: 0.04,
                half_length: 0.4,
            }
        }),
        obstacle(
            "block",
            [-0.4, 0.1, 0.6],
            [0.2, 0.5, 0.1],
            cuboid(0.08, 0.1, 0.12),
        ),
        obstacle("floor", [0.0, 0.0, -0.1], [0.0; 3], cuboid(2.0, 2.0, 0.05)),
    ]
}

/// The arm in the clutter, optionally holding a box (attached to the tip, touching nothing
/// else), or two arms facing each other.
fn worlds(dir: &Path) -> Vec<(&'static str, CollisionWorld)> {
    let arm = primitive_arm(dir);
    let mut one = CollisionWorld::single(arm.clone(), Pose::identity());
    one.statics = clutter();
    let mut held = one.clone();
    let q0 = vec![0.3, 0.6, 0.9, 0.0];
    let tip = arm.links.iter().position(|l| l.name == "tip").expect("tip");
    // A box in the hand: 0.1 m ahead of the tip frame (the tip's sphere touches it).
    let mut poses = vec![Pose::identity(); arm.links.len()];
    manyhands::kinematics::forward(&arm, &Pose::identity(), &q0, &mut poses);
    held.statics.push(StaticBody {
        name: "parcel".into(),
        kind: StaticKind::Object,
        pose: poses[tip] * iso_from_rpy([0.12, 0.0, 0.0], [0.0; 3]),
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Box {
                half_extents: Vector3::new(0.05, 0.06, 0.04),
            },
        }],
    });
    held.attach("parcel", 0, tip, &q0, vec![tip])
        .expect("attach");
    let mut two = CollisionWorld::single(arm.clone(), Pose::identity());
    two.statics = clutter()[3..].to_vec();
    two.robots.push(manyhands::collision::PlacedRobot {
        name: "prim_b".into(),
        robot: arm,
        base: iso_from_rpy([0.9, 0.05, 0.0], [0.0, 0.0, std::f64::consts::PI]),
        offset: 4,
    });
    vec![("one arm", one), ("attached box", held), ("two arms", two)]
}

/// Largest steps of the dense re-check: 0.002 rad and 1 mm per variable.
fn dense_steps(world: &CollisionWorld, a: &[f64], b: &[f64], angular: f64) -> usize {
    let mut n = 1.0f64;
    let mut v = 0;
    for p in &world.robots {
        for k in 0..p.robot.dof() {
            let j = &p.robot.joints[p.robot.vars[k]];
            let step = if j.kind == JointKind::Prismatic {
                0.001
            } else {
                angular
            };
            n = n.max(((b[v] - a[v]).abs() / step).ceil());
            v += 1;
        }
    }
    n as usize
}

/// Whether every state `a + (b − a)·k/n`, k = 0..=n, is free for `c`.
fn states_free(c: &mut impl CollisionChecker, a: &[f64], b: &[f64], n: usize) -> bool {
    let mut q = a.to_vec();
    (0..=n).all(|k| {
        let t = k as f64 / n as f64;
        for i in 0..q.len() {
            q[i] = a[i] + (b[i] - a[i]) * t;
        }
        c.is_free(&q)
    })
}

/// Grazing segments of `active` variables (the others at `start`), within the joint limits.
fn grazing(
    world: &CollisionWorld,
    start: &[f64],
    active: &[usize],
    count: usize,
    seed: u64,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut checker = FastChecker::new(world);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits: Vec<(f64, f64)> = world
        .robots
        .iter()
        .flat_map(|p| {
            (0..p.robot.dof()).map(|v| {
                let l = p.robot.var_limits(v);
                (l.lower, l.upper)
            })
        })
        .collect();
    let clamp = |q: &mut Vec<f64>| {
        for (i, v) in q.iter_mut().enumerate() {
            if !active.contains(&i) {
                *v = start[i];
            }
            *v = v.clamp(limits[i].0, limits[i].1);
        }
    };
    let mut out = Vec::new();
    // Random short segments first (most far from any contact), then grazing ones.
    while out.len() < count / 3 {
        let mut a = random_config_near(world, start, 0.3, 1.0, &mut rng);
        clamp(&mut a);
        let mut b = a.clone();
        for &v in active {
            b[v] += rng.random_range(-0.3..0.3);
        }
        clamp(&mut b);
        out.push((a, b));
    }
    let mut tries = 0;
    while out.len() < count && tries < 200 * count {
        tries += 1;
        let mut free = random_config_near(world, start, 0.3, 1.0, &mut rng);
        let mut hit = random_config_near(world, start, 0.3, 1.0, &mut rng);
        clamp(&mut free);
        clamp(&mut hit);
        if !checker.is_free(&free) || checker.is_free(&hit) {
            continue;
        }
        let away: Vec<f64> = free.iter().zip(&hit).map(|(f, h)| f - h).collect();
        for _ in 0..40 {
            let mid: Vec<f64> = free.iter().zip(&hit).map(|(x, y)| 0.5 * (x + y)).collect();
            if checker.is_free(&mid) {
                free = mid;
            } else {
                hit = mid;
            }
        }
        if rng.random::<f64>() < 0.4 {
            // A chord between two contact points close to each other: it dips into the
            // obstacle between them by little (what states 0.5° apart can miss).
            let mut other = free.clone();
            for &v in active {
                other[v] += rng.random_range(-0.08..0.08);
            }
            clamp(&mut other);
            if !checker.is_free(&other) {
                continue;
            }
            let mut inside = hit.clone();
            for _ in 0..40 {
                let mid: Vec<f64> = other
                    .iter()
                    .zip(&inside)
                    .map(|(x, y)| 0.5 * (x + y))
                    .collect();
                if checker.is_free(&mid) {
                    other = mid;
                } else {
                    inside = mid;
                }
            }
            // Both ends backed off from the contact by a little.
            let off = if rng.random::<f64>() < 0.5 {
                3e-4
            } else {
                3e-6
            };
            let (b0, b1) = (rng.random_range(0.0..off), rng.random_range(0.0..off));
            let a: Vec<f64> = free.iter().zip(&away).map(|(f, d)| f + d * b0).collect();
            let mut b: Vec<f64> = other.iter().zip(&away).map(|(f, d)| f + d * b1).collect();
            clamp(&mut b);
            out.push((a, b));
            continue;
        }
        // Back off from the contact by a little (up to 2 % of the way to the free state), or
        // go past it by less (a shallow penetration that states 0.5° apart can miss).
        let back: f64 = if rng.random::<f64>() < 0.5 {
            rng.random_range(0.0..0.02)
        } else {
            -rng.random_range(0.0..0.00003)
        };
        let p: Vec<f64> = free.iter().zip(&away).map(|(f, d)| f + d * back).collect();
        let len: f64 = rng.random_range(0.02..0.5);
        let (mut a, mut b) = (p.clone(), p.clone());
        let split: f64 = rng.random_range(0.0..1.0);
        let mut d: Vec<f64> = (0..p.len())
            .map(|v| {
                if active.contains(&v) {
                    rng.random_range(-1.0..1.0) * len
                } else {
                    0.0
                }
            })
            .collect();
        if back < 0.0 {
            // Along the contact (orthogonal to the way out in joint space), so the motion
            // only dips into the obstacle near `p`.
            let dot: f64 = d.iter().zip(&away).map(|(x, y)| x * y).sum();
            let n2: f64 = away.iter().map(|y| y * y).sum();
            for (x, y) in d.iter_mut().zip(&away) {
                *x -= dot / n2 * y;
            }
        }
        for &v in active {
            a[v] = p[v] - d[v] * split;
            b[v] = p[v] + d[v] * (1.0 - split);
        }
        clamp(&mut a);
        clamp(&mut b);
        out.push((a, b));
    }
    out
}

#[derive(Default, Debug)]
struct Tally {
    segments: usize,
    certified: usize,
    free_dense: usize,
    far: usize,
    far_certified: usize,
    /// Free at the 0.5° / 5 mm states but not at the dense ones (what a discrete check misses).
    missed_by_discrete: usize,
}

/// Checks `segments` in `world` with `cert` (a checker of the world, possibly for active
/// variables): certified ⇒ free at the dense states (exact and fast); far from contact ⇒
/// certified.
fn check_segments(
    name: &str,
    world: &CollisionWorld,
    cert: &mut FastChecker,
    segments: &[(Vec<f64>, Vec<f64>)],
) -> Tally {
    let mut exact = ExactChecker::new(world);
    let mut fast = FastChecker::new(world);
    let mut padded = FastChecker::with_settings(world, FastModelSettings { padding: 0.01 });
    let mut t = Tally::default();
    for (k, (a, b)) in segments.iter().enumerate() {
        t.segments += 1;
        let verdict = cert.certify_motion(a, b, FastChecker::CERTIFY_INFLATION);
        let n = dense_steps(world, a, b, 0.002);
        let fine = dense_steps(world, a, b, 0.0005);
        let fast_free = states_free(&mut fast, a, b, fine);
        if verdict == Certification::Free {
            t.certified += 1;
            assert!(
                fast_free,
                "{name} segment {k}: certified but a state collides in the fast model; a = {a:?}, b = {b:?}"
            );
            assert!(
                states_free(&mut exact, a, b, n),
                "{name} segment {k}: certified but the exact checker finds a collision; a = {a:?}, b = {b:?}"
            );
        }
        if fast_free {
            t.free_dense += 1;
            if states_free(&mut padded, a, b, n) {
                t.far += 1;
                assert_eq!(
                    verdict,
                    Certification::Free,
                    "{name} segment {k}: 1 cm from any contact but not certified; a = {a:?}, b = {b:?}"
                );
                t.far_certified += 1;
            }
        } else {
            assert_ne!(verdict, Certification::Free);
            let coarse = dense_steps(world, a, b, 0.5f64.to_radians()).max(
                // 5 mm steps for prismatic variables as the planners' resolution.
                dense_steps(world, a, b, 0.002) / 5,
            );
            if states_free(&mut fast, a, b, coarse) {
                t.missed_by_discrete += 1;
            }
        }
    }
    eprintln!("{name}: {t:?}");
    t
}

#[test]
fn certified_segments_of_primitive_robots_are_free_under_a_dense_exact_check() {
    let dir = common::tmp::run_root().join(format!("manyhands-certified-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let mut missed = 0;
    for (name, world) in worlds(&dir) {
        let start = vec![0.3; world.dof()];
        let active: Vec<usize> = (0..world.dof()).collect();
        let segs = grazing(&world, &start, &active, 600, 11);
        assert_eq!(segs.len(), 600, "{name}: grazing segments");
        let mut cert = FastChecker::new(&world);
        let t = check_segments(name, &world, &mut cert, &segs);
        missed += t.missed_by_discrete;
        // Both outcomes well represented, and most free segments proven.
        assert!(
            t.certified > 100 && t.segments - t.free_dense > 100 && t.far > 30,
            "{name}: {t:?}"
        );
        assert!(
            t.certified * 10 >= t.free_dense * 8,
            "{name}: only {} of {} segments free at the dense states certified",
            t.certified,
            t.free_dense
        );
    }
    eprintln!("{missed} segments free at the 0.5° states but not at the dense ones");
    let _ = std::fs::remove_dir_all(&dir);
}

fn kitchen() -> Scene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = load_robot_dir(&root.join("robots")).expect("robots");
    Scene::from_file(&root.join("scenes/kitchen.json"), &lib).expect("scene")
}

/// ARMAR's hip and right arm in the kitchen (the planners' checker, variables outside the chain
/// frozen), then with the wok held in the right hand and the left arm moving.
#[test]
fn certified_segments_of_armar_in_the_kitchen_are_free_under_a_dense_exact_check() {
    let s = kitchen();
    let world = CollisionWorld::from_scene(&s);
    let start = CollisionWorld::start_config(&s);
    let vars = |w: &CollisionWorld, g: &str| -> Vec<usize> {
        let p = &w.robots[0];
        p.robot
            .group(g)
            .expect("group")
            .vars
            .iter()
            .map(|v| p.offset + v)
            .collect()
    };
    let active = vars(&world, "torso_right_arm");
    let segs = grazing(&world, &start, &active, 300, 5);
    let mut cert = FastChecker::for_active(&world, FastModelSettings::default(), &active, &start);
    let t = check_segments("armar right arm", &world, &mut cert, &segs);
    assert!(t.certified > 50 && t.far > 10, "{t:?}");

    // The wok attached to the right hand where it lies (the hand links may touch it).
    let mut held = world.clone();
    let hand =
        manyhands::planning::problems::grasping::Hand::new(&held, "armar", "torso_right_arm")
            .expect("hand");
    let wok_link = hand.tcp_link();
    held.attach("wok", 0, wok_link, &start, hand.touch.clone())
        .expect("attach");
    let active = vars(&held, "torso_left_arm");
    let segs = grazing(&held, &start, &active, 300, 6);
    let mut cert = FastChecker::for_active(&held, FastModelSettings::default(), &active, &start);
    let t = check_segments("armar left arm, wok held", &held, &mut cert, &segs);
    assert!(t.certified > 20 && t.far > 0, "{t:?}");
}

/// A thin wall between two states of the planners' resolution: the discrete check of the
/// states passes it, the certified check does not (a slider, where the speed bound is exact,
/// and a swinging arm whose tip sweeps past a box edge between two states 0.5° apart).
#[test]
fn certified_check_refuses_what_the_states_miss() {
    let slider = r#"<robot name="slider">
  <link name="world"/>
  <link name="tool"><collision><geometry><sphere radius="0.0005"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="world"/><child link="tool"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
</robot>"#;
    let swing = r#"<robot name="swing">
  <link name="world"/>
  <link name="arm"><collision><origin xyz="0.5 0 0"/><geometry><box size="1.0 0.002 0.02"/></geometry></collision></link>
  <joint name="q" type="revolute"><parent link="world"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
</robot>"#;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut missed, mut refused) = (0, 0);
    for (urdf, step) in [(slider, 0.005), (swing, 0.5f64.to_radians())] {
        let robot = Arc::new(Robot::from_strings(urdf, None, Path::new(".")).expect("robot"));
        for _ in 0..200 {
            // A wall 0.6 mm thick somewhere between states k and k + 1 of 100 steps.
            let k = rng.random_range(10..90) as f64;
            let frac: f64 = rng.random_range(0.3..0.7);
            let s0 = (k + frac) * step;
            let pose = if urdf == slider {
                iso_from_rpy([s0, 0.0, 0.0], [0.0; 3])
            } else {
                // A post at radius 0.9 m, at angle s0, thin in the tangential direction.
                iso_from_rpy([0.9 * s0.cos(), 0.9 * s0.sin(), 0.0], [0.0, 0.0, s0])
            };
            let mut world = CollisionWorld::single(robot.clone(), Pose::identity());
            world.statics = vec![obstacle(
                "wall",
                [0.0; 3],
                [0.0; 3],
                Shape::Box {
                    half_extents: Vector3::new(0.02, 0.0003, 0.005),
                },
            )];
            world.statics[0].pose = if urdf == slider {
                pose * iso_from_rpy([0.0; 3], [0.0, 0.0, std::f64::consts::FRAC_PI_2])
            } else {
                pose
            };
            let (a, b) = ([0.0], [100.0 * step]);
            let mut fast = FastChecker::new(&world);
            let states = states_free(&mut fast, &a, &b, 100);
            let dense = states_free(&mut fast, &a, &b, 20_000);
            let cert = fast.motion_certified(&a, &b);
            assert!(!dense, "the wall at {s0} is on the way");
            assert!(!cert, "certified through the wall at {s0}");
            if states {
                missed += 1;
            }
            refused += 1;
        }
    }
    // Most walls fall between the states.
    assert!(
        missed > 300,
        "{missed} of {refused} walls between the states"
    );
}

/// Meant touching stays allowed, nothing else: before the grasp event every link of the hand is
/// checked against the object it is about to grasp (the approach ends free of it and is still
/// certified; moved 1.5 cm into the palm, the same approach is refused); from the grasp event on
/// the object is attached and the end effector's links may touch it (certified with the object
/// in the palm), no other link (refused with no touch links).
#[test]
fn only_the_grasping_hand_touches_the_object_from_the_grasp_on() {
    use manyhands::planning::problems::grasping::ReachProblem;
    use manyhands::planning::tasks::task::{reach_task, GraspAlgorithm};
    use manyhands::planning::{IkRrtSettings, Termination};

    let s = kitchen();
    let ik = manyhands::kinematics::randomized::RandomizedIkSettings {
        max_tries: 50,
        ..Default::default()
    };
    let plan = reach_task(
        &s,
        "armar",
        "torso_right_arm",
        "wok",
        None,
        GraspAlgorithm::IkRrt,
        IkRrtSettings::default(),
        ik,
        &mut Termination::new(),
        3,
    )
    .expect("grasp plan");
    let ph = &plan.phases[0];
    let (qa, qg) = (&plan.waypoints[ph.last - 1], &plan.waypoints[ph.last]);
    // The approach, ending at the grasp state: certified in the world it was planned in.
    assert!(FastChecker::new(&ph.world).motion_certified(qa, qg));

    let world = CollisionWorld::from_scene(&s);
    let start = CollisionWorld::start_config(&s);
    let p = ReachProblem::grasp(&s, &world, &start, "armar", "torso_right_arm", "wok")
        .expect("problem");
    let tcp = p.hand.tcp_pose(&world, qg);
    let approach = tcp.rotation * Vector3::z();
    let wi = world
        .statics
        .iter()
        .position(|b| b.name == "wok")
        .expect("wok");
    // Before the grasp: the wok 1.5 cm further into the hand is hit by the approach.
    let mut deeper = world.clone();
    deeper.statics[wi].pose.translation.vector -= approach * 0.015;
    let mut c = FastChecker::new(&deeper);
    assert!(!c.is_free(qg), "the shifted wok must overlap the hand");
    assert!(!c.motion_certified(qa, qg));

    // From the grasp on: attached 1.5 cm into the palm (where `deeper` has it).
    // (Without the fixed bodies: the wok pushed into the palm would reach into the counter.)
    let mut held = deeper.clone();
    held.statics.retain(|b| b.name == "wok");
    held.attach(
        "wok",
        p.hand.robot,
        p.hand.tcp_link(),
        qg,
        p.hand.touch.clone(),
    )
    .expect("attach");
    let mut lifted = qg.clone();
    let hip = p.space.vars()[0];
    lifted[hip] += 0.05;
    let mut c = FastChecker::new(&held);
    assert!(
        c.motion_certified(qg, &lifted),
        "the hand may touch what it holds: {:?}",
        c.first_contact(qg)
    );
    // No touch links: the same motion is refused (the hand touches the held wok).
    held.attached[0].touch.clear();
    let mut c = FastChecker::new(&held);
    assert!(!c.is_free(qg));
    assert!(!c.motion_certified(qg, &lifted));
}

/// A motion ending at touching distance (5 µm from a wall, far below the 0.5° / 5 mm states'
/// reach) is certified, in both directions; ending within the 1 µm refinement floor of it, or
/// 0.1 µm inside, is not.
#[test]
fn a_motion_ending_at_touching_distance_is_certified() {
    let urdf = r#"<robot name="slider">
  <link name="world"/>
  <link name="tool"><collision><geometry><sphere radius="0.01"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="world"/><child link="tool"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
</robot>"#;
    let robot = Arc::new(Robot::from_strings(urdf, None, Path::new(".")).expect("robot"));
    let mut world = CollisionWorld::single(robot, Pose::identity());
    // Wall face at x = 0.5.
    world.statics = vec![obstacle(
        "wall",
        [0.55, 0.0, 0.0],
        [0.0; 3],
        Shape::Box {
            half_extents: Vector3::new(0.05, 0.2, 0.2),
        },
    )];
    let mut c = FastChecker::new(&world);
    for (gap, free) in [(5e-6, true), (1e-5, true), (5e-7, false), (-1e-7, false)] {
        let end = 0.5 - 0.01 - gap;
        assert_eq!(c.motion_certified(&[-0.3], &[end]), free, "gap {gap}");
        assert_eq!(
            c.motion_certified(&[end], &[-0.3]),
            free,
            "gap {gap}, leaving"
        );
    }
}
