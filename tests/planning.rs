//! The planning core: RRT-Connect on small robots (a planar 2-link arm around a wall, a point
//! probe in a closed room), determinism by seed, clean failures, termination and shortcutting.
//! Every path is re-checked by the exact checker at 5 mm / 0.5°.

use std::f64::consts::FRAC_PI_2;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use manyhands::collision::{CollisionWorld, ExactChecker, StaticBody, StaticKind};
use manyhands::geometry::{iso_from_rpy, Geometry, Pose, Shape};
use manyhands::planning::base::shortcut::simplify;
use manyhands::planning::{
    JointSpace, PlanError, PlanResult, RrtConnect, RrtConnectSettings, Sampler, ShortcutSettings,
    SpaceValidator, Termination,
};
use manyhands::Robot;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

// ---------------------------------------------------------------------------------------------
// Fixtures

fn wall(name: &str, pos: [f64; 3], half: [f64; 3]) -> StaticBody {
    StaticBody {
        name: name.into(),
        kind: StaticKind::Obstacle,
        pose: iso_from_rpy(pos, [0.0; 3]),
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Box {
                half_extents: Vector3::from(half),
            },
        }],
    }
}

/// Planar arm turning about z: link1 a box along x (length 1), link2 a cylinder along x (length
/// 0.8, radius 0.05), a small box hand at its tip. Limits ±3.
fn arm() -> Arc<Robot> {
    let j = |name: &str, parent: &str, child: &str, xyz: &str| {
        format!(
            r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>
               <origin xyz="{xyz}"/><axis xyz="0 0 1"/>
               <limit lower="-3" upper="3" velocity="1" effort="1"/></joint>"#
        )
    };
    let urdf = format!(
        r#"<robot name="arm">
  <link name="base"/>
  <link name="link1"><collision><origin xyz="0.5 0 0"/>
    <geometry><box size="1 0.1 0.1"/></geometry></collision></link>
  <link name="link2"><collision><origin xyz="0.4 0 0" rpy="0 {h} 0"/>
    <geometry><cylinder radius="0.05" length="0.8"/></geometry></collision></link>
  <link name="hand"><collision><origin xyz="0.05 0 0"/>
    <geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  {j1}{j2}
  <joint name="j3" type="fixed"><parent link="link2"/><child link="hand"/><origin xyz="0.8 0 0"/></joint>
</robot>"#,
        h = FRAC_PI_2,
        j1 = j("j1", "base", "link1", "0 0 0"),
        j2 = j("j2", "link1", "link2", "1 0 0"),
    );
    let srdf = r#"<robot name="arm">
  <disable_collisions link1="link1" link2="link2" reason="Adjacent"/>
  <disable_collisions link1="link2" link2="hand" reason="Adjacent"/>
</robot>"#;
    Arc::new(Robot::from_strings(&urdf, Some(srdf), Path::new(".")).expect("arm model"))
}

/// The arm with a wall at x = 1.3…1.5 across y = ±0.15: the stretched arm cannot sweep
/// from j1 = +1.2 to j1 = −1.2, it must fold its elbow to pass.
fn arm_world() -> CollisionWorld {
    let mut w = CollisionWorld::single(arm(), Pose::identity());
    w.statics
        .push(wall("wall", [1.4, 0.0, 0.0], [0.1, 0.15, 0.5]));
    w
}

/// A point probe (prismatic x, y in [-2, 2]) carrying a sphere of radius 0.1.
fn probe() -> Arc<Robot> {
    let pj = |name: &str, parent: &str, child: &str, axis: &str| {
        format!(
            r#"<joint name="{name}" type="prismatic"><parent link="{parent}"/><child link="{child}"/>
               <axis xyz="{axis}"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>"#
        )
    };
    let urdf = format!(
        r#"<robot name="probe"><link name="world"/><link name="px"/>
  <link name="tool"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
  {}{}</robot>"#,
        pj("x", "world", "px", "1 0 0"),
        pj("y", "px", "tool", "0 1 0"),
    );
    Arc::new(Robot::from_strings(&urdf, None, Path::new(".")).expect("probe model"))
}

/// The probe with a closed square room (walls 0.1 thick) around (1, 1).
fn room_world() -> CollisionWorld {
    let mut w = CollisionWorld::single(probe(), Pose::identity());
    w.statics.push(wall("n", [1.0, 1.5, 0.0], [0.6, 0.05, 0.5]));
    w.statics.push(wall("s", [1.0, 0.5, 0.0], [0.6, 0.05, 0.5]));
    w.statics.push(wall("e", [1.5, 1.0, 0.0], [0.05, 0.6, 0.5]));
    w.statics.push(wall("w", [0.5, 1.0, 0.0], [0.05, 0.6, 0.5]));
    w
}

fn planner(world: &CollisionWorld, settings: RrtConnectSettings) -> RrtConnect {
    let space = JointSpace::all(world, vec![0.0; world.dof()]).expect("space");
    RrtConnect::new(space, world, settings).expect("planner")
}

fn raw_settings() -> RrtConnectSettings {
    RrtConnectSettings {
        shortcut: None,
        ..RrtConnectSettings::default()
    }
}

fn term(ms: u64) -> Termination {
    Termination::new().with_time_limit(Duration::from_millis(ms))
}

/// Exact checker at 5 mm / 0.5°: `Err(k)` names the first bad state or segment.
fn exact_check(world: &CollisionWorld, space: &JointSpace, path: &[Vec<f64>]) -> Result<(), usize> {
    SpaceValidator::new(
        space.clone(),
        world,
        ExactChecker::new(world),
        0.5f64.to_radians(),
        0.005,
    )
    .validate_path(path)
}

fn assert_solution(
    world: &CollisionWorld,
    space: &JointSpace,
    r: &PlanResult,
    start: &[f64],
    goals: &[Vec<f64>],
) {
    assert!(r.path.len() >= 2);
    assert_eq!(r.path[0], start);
    assert_eq!(
        r.path.last().map(|q| q.as_slice()),
        Some(goals[r.goal_index].as_slice())
    );
    for q in &r.path {
        assert!(space.satisfies_bounds(q), "outside the limits: {q:?}");
    }
    assert_eq!(exact_check(world, space, &r.path), Ok(()));
    let len = space.path_length(&r.path);
    assert!((len - r.stats.length_simplified).abs() < 1e-9);
    assert!(r.stats.length_simplified <= r.stats.length_raw + 1e-9);
}

const ARM_START: [f64; 2] = [1.2, 0.0];
const ARM_GOAL: [f64; 2] = [-1.2, 0.0];

// ---------------------------------------------------------------------------------------------
// Tests

#[test]
fn arm_goes_around_the_wall() {
    let w = arm_world();
    let mut p = planner(&w, RrtConnectSettings::default());
    let space = p.space().clone();
    let goals = vec![ARM_GOAL.to_vec()];
    // The straight joint-space segment is blocked: the planner must really search.
    assert!(!p.validator().is_motion_valid(&ARM_START, &ARM_GOAL));
    for seed in 0..10 {
        let r = p
            .plan(&ARM_START, &goals, &mut term(2000), seed)
            .expect("solved");
        assert_solution(&w, &space, &r, &ARM_START, &goals);
        assert!(r.path.len() >= 3, "a path around the wall has a corner");
        assert!(r.stats.iterations > 0 && r.stats.collision_checks > 0);
        assert!(r.stats.start_tree_size >= 1 && r.stats.goal_tree_size >= 1);
    }
}

#[test]
fn halton_sampler_gives_one_search_for_every_seed() {
    let w = arm_world();
    let settings = RrtConnectSettings {
        sampler: Sampler::Halton,
        ..raw_settings()
    };
    let mut p = planner(&w, settings);
    let space = p.space().clone();
    let goals = vec![ARM_GOAL.to_vec()];
    let a = p
        .plan(&ARM_START, &goals, &mut term(2000), 1)
        .expect("solved");
    assert_solution(&w, &space, &a, &ARM_START, &goals);
    assert!(a.path.len() >= 3, "a path around the wall has a corner");
    for seed in [2, 99] {
        let b = p
            .plan(&ARM_START, &goals, &mut term(2000), seed)
            .expect("solved");
        assert_eq!(a.path, b.path, "seed {seed}");
        assert_eq!(a.stats.iterations, b.stats.iterations);
    }
    // With dynamic-domain sampling and balanced trees too (the skipped samples are drawn in
    // one loop), and the uniform sampler still differs by seed.
    let dd = RrtConnectSettings {
        dynamic_domain: Some(1.0),
        balance: true,
        ..settings
    };
    let mut p = planner(&w, dd);
    let c = p
        .plan(&ARM_START, &goals, &mut term(2000), 1)
        .expect("solved");
    assert_solution(&w, &space, &c, &ARM_START, &goals);
    let d = p
        .plan(&ARM_START, &goals, &mut term(2000), 5)
        .expect("solved");
    assert_eq!(c.path, d.path);
    let mut u = planner(&w, raw_settings());
    let paths: Vec<_> = (1..=3)
        .map(|seed| {
            u.plan(&ARM_START, &goals, &mut term(2000), seed)
                .expect("solved")
                .path
        })
        .collect();
    assert!(paths[0] != paths[1] || paths[1] != paths[2]);
}

#[test]
fn goal_set_reaches_one_goal_and_reports_which() {
    let w = arm_world();
    let mut p = planner(&w, RrtConnectSettings::default());
    let space = p.space().clone();
    // Goal 0 is in the wall (skipped), goal 1 is free.
    let goals = vec![vec![0.0, 0.0], vec![-1.2, 0.3]];
    let r = p
        .plan(&ARM_START, &goals, &mut term(2000), 3)
        .expect("solved");
    assert_eq!(r.goal_index, 1);
    assert_solution(&w, &space, &r, &ARM_START, &goals);
}

#[test]
fn same_seed_same_path_other_seed_other_path() {
    let w = arm_world();
    let mut p = planner(&w, RrtConnectSettings::default());
    let goals = vec![ARM_GOAL.to_vec()];
    let a = p
        .plan(&ARM_START, &goals, &mut term(2000), 42)
        .expect("solved");
    let b = p
        .plan(&ARM_START, &goals, &mut term(2000), 42)
        .expect("solved");
    assert_eq!(a.path, b.path);
    assert_eq!(a.stats.iterations, b.stats.iterations);
    // A fresh planner gives the same result too (no state leaks between queries).
    let c = planner(&w, RrtConnectSettings::default())
        .plan(&ARM_START, &goals, &mut term(2000), 42)
        .expect("solved");
    assert_eq!(a.path, c.path);
    let d = p
        .plan(&ARM_START, &goals, &mut term(2000), 43)
        .expect("solved");
    assert_ne!(a.path, d.path);
}

#[test]
fn goal_inside_an_obstacle_is_a_clean_error() {
    let w = arm_world();
    let mut p = planner(&w, RrtConnectSettings::default());
    let t = Instant::now();
    match p.plan(&ARM_START, &[vec![0.0, 0.0]], &mut term(1000), 1) {
        Err(PlanError::InvalidGoal { count: 1, reason }) => {
            assert!(reason.contains("obstacle:wall"), "{reason}")
        }
        other => panic!("expected InvalidGoal, got {other:?}"),
    }
    assert!(t.elapsed() < Duration::from_millis(100));
    // Outside the joint limits.
    match p.plan(&ARM_START, &[vec![-1.2, 3.5]], &mut term(1000), 1) {
        Err(PlanError::InvalidGoal { reason, .. }) => assert!(reason.contains("j2"), "{reason}"),
        other => panic!("expected InvalidGoal, got {other:?}"),
    }
    // Start in the wall; wrong dimension.
    assert!(matches!(
        p.plan(&[0.0, 0.0], &[ARM_GOAL.to_vec()], &mut term(1000), 1),
        Err(PlanError::InvalidStart { .. })
    ));
    assert!(matches!(
        p.plan(&[1.2], &[ARM_GOAL.to_vec()], &mut term(1000), 1),
        Err(PlanError::InvalidStart { .. })
    ));
    assert!(matches!(
        p.plan(&ARM_START, &[], &mut term(1000), 1),
        Err(PlanError::InvalidGoal { count: 0, .. })
    ));
}

#[test]
fn goal_behind_a_closed_wall_times_out_in_time() {
    let w = room_world();
    let mut p = planner(&w, RrtConnectSettings::default());
    for limit in [30u64, 100] {
        // Up to three tries, so a scheduler hiccup on a loaded 2-core machine does not fail the
        // test; a planner that overruns its deadline fails every try.
        let mut best = Duration::MAX;
        for _ in 0..3 {
            let mut t = term(limit);
            let s = Instant::now();
            let r = p.plan(&[-1.0, -1.0], &[vec![1.0, 1.0]], &mut t, 5);
            let e = s.elapsed();
            match r {
                Err(PlanError::Timeout { stats }) => {
                    assert!(stats.iterations > 10, "{stats:?}");
                    assert!(stats.start_tree_size > 1);
                }
                other => panic!("expected Timeout, got {other:?}"),
            }
            assert!(e >= Duration::from_millis(limit), "{e:?}");
            assert!(
                e <= Duration::from_millis(limit + 100),
                "took {e:?} for a {limit} ms limit"
            );
            best = best.min(e);
            if best <= Duration::from_millis(limit + 10) {
                break;
            }
        }
        assert!(
            best <= Duration::from_millis(limit + 10),
            "took {best:?} (best of 3) for a {limit} ms limit"
        );
    }
    // The room's inside is reachable from the inside.
    let r = p
        .plan(&[0.8, 0.8], &[vec![1.2, 1.2]], &mut term(1000), 5)
        .expect("solved inside");
    assert_solution(&w, &p.space().clone(), &r, &[0.8, 0.8], &[vec![1.2, 1.2]]);
}

#[test]
fn iteration_limit_and_stop_flag() {
    let w = room_world();
    let mut p = planner(&w, RrtConnectSettings::default());
    let mut t = Termination::new().with_iteration_limit(50);
    match p.plan(&[-1.0, -1.0], &[vec![1.0, 1.0]], &mut t, 1) {
        Err(PlanError::IterationLimit { stats }) => assert_eq!(stats.iterations, 50),
        other => panic!("expected IterationLimit, got {other:?}"),
    }
    // Raised before the call: stops at once.
    let flag = Arc::new(AtomicBool::new(true));
    let mut t = Termination::new().with_stop_flag(flag.clone());
    match p.plan(&[-1.0, -1.0], &[vec![1.0, 1.0]], &mut t, 1) {
        Err(PlanError::Stopped { stats }) => assert_eq!(stats.iterations, 0),
        other => panic!("expected Stopped, got {other:?}"),
    }
    // Raised from another thread after 20 ms.
    flag.store(false, Ordering::Relaxed);
    let f2 = flag.clone();
    let h = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(20));
        f2.store(true, Ordering::Relaxed);
    });
    let s = Instant::now();
    let mut t = Termination::new()
        .with_stop_flag(flag)
        .with_time_limit(Duration::from_secs(10));
    let r = p.plan(&[-1.0, -1.0], &[vec![1.0, 1.0]], &mut t, 1);
    let e = s.elapsed();
    h.join().expect("thread");
    assert!(matches!(r, Err(PlanError::Stopped { .. })), "{r:?}");
    assert!(e < Duration::from_millis(500), "{e:?}");
}

#[test]
fn shortcutting_never_lengthens_and_stays_valid() {
    let w = arm_world();
    let mut p = planner(&w, raw_settings());
    let space = p.space().clone();
    let goals = vec![ARM_GOAL.to_vec()];
    let mut shortened = 0;
    for seed in 0..10 {
        let r = p
            .plan(&ARM_START, &goals, &mut term(2000), seed)
            .expect("solved");
        assert_eq!(r.stats.length_raw, r.stats.length_simplified);
        let raw = r.path.clone();
        let raw_len = space.path_length(&raw);
        let mut path = raw.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let st = simplify(
            p.validator(),
            &mut path,
            &ShortcutSettings::default(),
            &mut rng,
            &mut Termination::new(),
        );
        assert!(!st.reverted);
        let len = space.path_length(&path);
        assert!(len <= raw_len + 1e-12, "seed {seed}: {len} > {raw_len}");
        if len < raw_len - 1e-6 {
            shortened += 1;
        }
        assert_eq!(path.first(), raw.first());
        assert_eq!(path.last(), raw.last());
        assert_eq!(exact_check(&w, &space, &path), Ok(()), "seed {seed}");
    }
    assert!(
        shortened >= 5,
        "shortcutting shortened only {shortened} of 10 paths"
    );
}

/// Random shortcuts that would gain less than `min_gain` of the path's length are not tried
/// (no motion check), larger gains still are.
#[test]
fn shortcuts_below_the_minimum_gain_are_not_checked() {
    let w = CollisionWorld::single(arm(), Pose::identity());
    let mut p = planner(&w, raw_settings());
    // A detour of 0.02 rad at the middle: the path is 0.017 % longer than the straight one.
    let path0 = vec![ARM_START.to_vec(), vec![0.0, 0.02], ARM_GOAL.to_vec()];
    let len0 = p.space().path_length(&path0);
    for (min_gain, tried) in [(0.0, true), (0.01, false)] {
        let settings = ShortcutSettings {
            vertex_removal: false,
            min_gain,
            ..ShortcutSettings::default()
        };
        let mut path = path0.clone();
        let segments = p.validator().segments();
        let st = simplify(
            p.validator(),
            &mut path,
            &settings,
            &mut ChaCha8Rng::seed_from_u64(1),
            &mut Termination::new(),
        );
        // Motion checks besides the final validation of the result's segments.
        let checked = p.validator().segments() - segments - (path.len() as u64 - 1);
        let len = p.space().path_length(&path);
        assert!(!st.reverted);
        if tried {
            assert!(st.shortcuts > 0 && checked > 0, "{st:?}");
            assert!(len < len0 - 1e-6, "{len} vs {len0}");
        } else {
            assert_eq!((st.shortcuts, checked), (0, 0), "{st:?}");
            assert_eq!(path, path0);
        }
    }
}

#[test]
fn direct_connection_when_nothing_is_in_the_way() {
    let w = CollisionWorld::single(arm(), Pose::identity());
    let mut p = planner(&w, RrtConnectSettings::default());
    let r = p
        .plan(&ARM_START, &[ARM_GOAL.to_vec()], &mut term(1000), 1)
        .expect("solved");
    assert_eq!(r.path, vec![ARM_START.to_vec(), ARM_GOAL.to_vec()]);
    assert_eq!(r.stats.iterations, 0);
}

#[test]
fn exact_checker_rejects_a_path_through_the_wall() {
    let w = arm_world();
    let space = JointSpace::all(&w, vec![0.0; 2]).expect("space");
    // Both ends free, the straight segment sweeps the stretched arm through the wall.
    assert_eq!(
        exact_check(&w, &space, &[ARM_START.to_vec(), ARM_GOAL.to_vec()]),
        Err(1)
    );
    assert_eq!(
        exact_check(&w, &space, &[ARM_START.to_vec(), vec![1.2, 3.5]]),
        Err(1)
    );
}

#[test]
fn space_sampling_distance_and_bounds() {
    let w = arm_world();
    let space = JointSpace::all(&w, vec![0.0; 2])
        .expect("space")
        .with_weights(vec![1.0, 4.0])
        .expect("weights");
    assert_eq!(space.dim(), 2);
    assert!((space.distance(&[0.0, 0.0], &[1.0, 1.0]) - 5f64.sqrt()).abs() < 1e-12);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut q = [0.0; 2];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for _ in 0..2000 {
        space.sample_uniform(&mut rng, &mut q);
        assert!(space.satisfies_bounds(&q));
        for i in 0..2 {
            lo[i] = lo[i].min(q[i]);
            hi[i] = hi[i].max(q[i]);
        }
    }
    for i in 0..2 {
        assert!(
            lo[i] < -2.9 && hi[i] > 2.9,
            "samples do not cover the limits: {lo:?} {hi:?}"
        );
    }
    let mut m = [0.0; 2];
    space.interpolate(&[0.0, 1.0], &[2.0, -1.0], 0.25, &mut m);
    assert_eq!(m, [0.5, 0.5]);
    assert!(JointSpace::new(&w, &[2], vec![0.0; 2]).is_err());
    assert!(JointSpace::new(&w, &[0, 0], vec![0.0; 2]).is_err());
    assert!(JointSpace::new(&w, &[1], vec![0.0; 3]).is_err());
    assert!(space.clone().with_weights(vec![1.0, 0.0]).is_err());
}
