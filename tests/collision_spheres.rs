//! The f32 sphere checker against the exact f64 checker: never "free" where exact collides,
//! "free" wherever exact is free by more than the sphere model's margin; 8-lane segment checks
//! agree with state-by-state checks; certified segments are free. On the suite's own two-arm
//! sphere robot (`tests/robots/twin_arms`) among obstacles the test draws itself (always), and on
//! the MotionBenchMaker scenes of Panda and Baxter (skipped without their data, see
//! `manyhands::benchmark::mbm_data`).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use manyhands::benchmark::mbm::{MbmFile, MbmObstacle, MbmProblem, MbmSet};
use manyhands::benchmark::mbm_data::data_for_test;
use manyhands::collision::{
    AutoChecker, CertifyCounts, CollisionChecker, CollisionWorld, ExactChecker, SegmentScreen,
    SphereChecker,
};
use manyhands::geometry::{iso_from_rpy, Pose, Shape};
use manyhands::Robot;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A configuration with the planned variables `vars` uniform within their limits, the others 0.
fn random_config(r: &Robot, vars: &[usize], rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut q = r.zero_config();
    for &v in vars {
        let l = r.var_limits(v);
        q[v] = rng.random_range(l.lower..=l.upper);
    }
    q
}

/// A MotionBenchMaker robot and its problem file (`None` without the data: the test is skipped).
fn mbm(name: &str) -> Option<(Arc<Robot>, MbmFile)> {
    let dir = data_for_test()?;
    Some(mbm_in(&dir, name))
}

fn mbm_in(dir: &Path, name: &str) -> (Arc<Robot>, MbmFile) {
    let d = dir.join(name);
    let r = Arc::new(
        Robot::from_files(
            &d.join(format!("{name}_spherized.urdf")),
            Some(&d.join(format!("{name}.srdf"))),
        )
        .expect("robot"),
    );
    let file = MbmFile::load(&d.join("problems.json")).expect("problems");
    (r, file)
}

/// The suite's own sphere robot: two arms with the Panda's kinematics on a torso.
fn twin_arms() -> Arc<Robot> {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/robots");
    Arc::new(
        Robot::from_files(&d.join("twin_arms.urdf"), Some(&d.join("twin_arms.srdf")))
            .expect("tests/robots/twin_arms"),
    )
}

/// Problems for `twin_arms` written here, in the benchmark's form: three sets of three, each
/// with eight obstacles (boxes, cylinders and spheres of 3–15 cm, at random poses in front of
/// and between the arms) that leave `ready` free by 2 cm, start `ready`, three free goals.
fn twin_problems() -> (Arc<Robot>, MbmFile) {
    let r = twin_arms();
    let joints: Vec<String> = (0..r.dof()).map(|v| r.var_name(v).to_string()).collect();
    let all: Vec<usize> = (0..r.dof()).collect();
    let ready = r.named_config("ready").expect("ready");
    let bare = CollisionWorld::single(r.clone(), Pose::identity());
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    let mut sets = Vec::new();
    for set in ["front", "between", "clutter"] {
        let mut problems = Vec::new();
        for index in 1..=3 {
            let mut p = MbmProblem {
                set: set.to_string(),
                index,
                valid: true,
                start: ready.clone(),
                goals: Vec::new(),
                obstacles: Vec::new(),
            };
            while p.obstacles.len() < 8 {
                let y = match set {
                    "front" => rng.random_range(-0.6..0.6),
                    "between" => rng.random_range(-0.2..0.2),
                    _ => rng.random_range(-0.9..0.9),
                };
                let pos = [rng.random_range(0.2..0.8), y, rng.random_range(0.1..1.3)];
                let rpy = [
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-3.0..3.0),
                ];
                let mut size = || rng.random_range(0.03..0.15);
                let shape = match p.obstacles.len() % 3 {
                    0 => Shape::Box {
                        half_extents: Vector3::new(size(), size(), size()),
                    },
                    1 => Shape::Cylinder {
                        radius: size() * 0.5,
                        half_length: size(),
                    },
                    _ => Shape::Sphere { radius: size() },
                };
                let o = MbmObstacle {
                    name: format!("o{}", p.obstacles.len()),
                    pose: iso_from_rpy(pos, rpy),
                    shape,
                };
                p.obstacles.push(o);
                let world = p.world(r.clone());
                if !ExactChecker::new(&world).is_free_with_margin(&ready, 0.02) {
                    p.obstacles.pop();
                }
            }
            let world = p.world(r.clone());
            let mut exact = ExactChecker::new(&world);
            while p.goals.len() < 3 {
                let q = random_config(&r, &all, &mut rng);
                if exact.is_free(&q) {
                    p.goals.push(q);
                }
            }
            problems.push(p);
        }
        sets.push(MbmSet {
            name: set.to_string(),
            problems,
        });
    }
    assert!(
        ExactChecker::new(&bare).is_free(&ready),
        "ready is self-collision-free"
    );
    (
        r,
        MbmFile {
            robot: "twin_arms".into(),
            joints,
            sets,
            generated: false,
        },
    )
}

/// Random configurations, half uniform in the limits, half near the problem's start and goals
/// (where contacts are close); returns (exact collisions, exact free with margin).
fn compare(
    (r, file): (Arc<Robot>, MbmFile),
    per_problem: usize,
    padding: f64,
) -> (usize, usize, usize) {
    let vars = file.joint_vars(&r).expect("vars");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut hits, mut clear, mut total) = (0, 0, 0);
    for set in &file.sets {
        for p in set.problems.iter().filter(|p| p.valid).take(3) {
            let world = p.world(r.clone());
            let mut sc = SphereChecker::new(&world, padding).expect("a sphere robot");
            let margin = sc.max_overapproximation();
            assert!(margin < 2.0 * padding + 1e-3);
            let mut exact = ExactChecker::new(&world);
            let base = r.zero_config();
            let anchors: Vec<&Vec<f64>> = std::iter::once(&p.start).chain(&p.goals).collect();
            for k in 0..per_problem {
                let mut q = base.clone();
                for (i, &v) in vars.iter().enumerate() {
                    let l = r.var_limits(v);
                    q[v] = if k % 2 == 0 {
                        rng.random_range(l.lower..=l.upper)
                    } else {
                        let a = anchors[k / 2 % anchors.len()][i];
                        (a + rng.random_range(-0.3..0.3)).clamp(l.lower, l.upper)
                    };
                }
                total += 1;
                let s = sc.is_free(&q);
                if !exact.is_free(&q) {
                    hits += 1;
                    assert!(
                        !s,
                        "{}[{}]: exact collides, spheres free; q = {q:?}",
                        p.set, p.index
                    );
                } else if exact.is_free_with_margin(&q, margin) {
                    clear += 1;
                    assert!(
                        s,
                        "{}[{}]: exact free by > {margin}, spheres collide ({:?}); q = {q:?}",
                        p.set,
                        p.index,
                        sc.first_contact(&q)
                    );
                }
                // Start and goals of valid problems are free for the unpadded model.
                if padding == 0.0 && k == 0 {
                    assert!(sc.is_free(&p.start), "{}[{}] start", p.set, p.index);
                }
            }
        }
    }
    (hits, clear, total)
}

#[test]
fn twin_arms_spheres_agree_with_exact() {
    let (hits, clear, total) = compare(twin_problems(), 1500, 0.0);
    assert!(
        hits > total / 10 && clear > total / 10,
        "{hits} {clear} {total}"
    );
}

#[test]
fn twin_arms_padded_spheres_are_conservative() {
    let (hits, clear, total) = compare(twin_problems(), 300, 0.005);
    assert!(hits > 0 && clear > 0, "{hits} {clear} {total}");
}

#[test]
fn panda_spheres_agree_with_exact() {
    let Some(data) = mbm("panda") else { return };
    let (hits, clear, total) = compare(data, 1500, 0.0);
    assert!(
        hits > total / 10 && clear > total / 10,
        "{hits} {clear} {total}"
    );
}

#[test]
fn panda_padded_spheres_are_conservative() {
    let Some(data) = mbm("panda") else { return };
    let (hits, clear, total) = compare(data, 300, 0.005);
    assert!(hits > 0 && clear > 0, "{hits} {clear} {total}");
}

#[test]
fn baxter_spheres_agree_with_exact() {
    let Some(data) = mbm("baxter") else { return };
    let (hits, clear, total) = compare(data, 1500, 0.0);
    assert!(
        hits > total / 10 && clear > total / 10,
        "{hits} {clear} {total}"
    );
}

#[test]
fn segment_check_equals_state_by_state() {
    segment_check_equals_state_by_state_on(twin_problems());
}

#[test]
fn segment_check_equals_state_by_state_on_panda() {
    let Some(data) = mbm("panda") else { return };
    segment_check_equals_state_by_state_on(data);
}

fn segment_check_equals_state_by_state_on((r, file): (Arc<Robot>, MbmFile)) {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for set in &file.sets {
        let p = set.problems.iter().find(|p| p.valid).expect("valid");
        let world = p.world(r.clone());
        let mut sc = SphereChecker::new(&world, 0.0).expect("spheres");
        let mut single = sc.clone();
        for _ in 0..200 {
            let g = &p.goals[rng.random_range(0..p.goals.len())];
            let a: Vec<f64> = p
                .start
                .iter()
                .map(|v| v + rng.random_range(-0.5..0.5))
                .collect();
            let b: Vec<f64> = g.iter().map(|v| v + rng.random_range(-0.5..0.5)).collect();
            let n = rng.random_range(1..60);
            let each = (1..=n).all(|k| {
                let t = k as f64 / n as f64;
                let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect();
                single.is_free(&q)
            });
            assert_eq!(sc.segment_free(&a, &b, n), each, "{} n = {n}", p.set);
        }
    }
}

/// The node-level cull of self-pair groups (grippers of several spheres on one node each)
/// changes no result and no refinement, end to end: single states, plain segments and
/// certified segments give the same verdicts and the same number of checked states with the
/// cull on and off, with no obstacles (self pairs decide), on segments from free states to
/// colliding ones. (That the cull bounds every pair it skips, inflations included, is tested
/// directly in the module: `node_cull_bounds_every_pair_of_its_group`.)
/// Segment `k` (`a → b`) gets the same certified verdict with the same number of checked
/// states from both checkers (but for a hot start's early collision, see below), and the same
/// discrete verdict at a random resolution; returns the certified verdict.
fn same_segment_verdicts(
    on: &mut SphereChecker,
    off: &mut SphereChecker,
    a: &[f64],
    b: &[f64],
    rng: &mut ChaCha8Rng,
    k: usize,
) -> bool {
    let (c0, d0) = (on.checks(), off.checks());
    let v = on.segment_certified(a, b, 0.04);
    assert_eq!(v, off.segment_certified(a, b, 0.04), "segment {k}");
    // The same states, except that a certified check with a hot body first tests the hot
    // and warm bodies at 8 states spread over the whole segment (its first call's when it
    // makes one): a collision there ends it before later calls.
    let (con, coff) = (on.checks() - c0, off.checks() - d0);
    assert!(
        con == coff || (!v && con == 8 && coff > 8),
        "segment {k}: {con} against {coff} states"
    );
    let n = rng.random_range(1..40);
    assert_eq!(
        on.segment_free(a, b, n),
        off.segment_free(a, b, n),
        "segment {k}"
    );
    v
}

#[test]
fn node_cull_changes_nothing() {
    node_cull_changes_nothing_on(twin_problems());
}

#[test]
fn node_cull_changes_nothing_on_baxter() {
    let Some(data) = mbm("baxter") else { return };
    node_cull_changes_nothing_on(data);
}

fn node_cull_changes_nothing_on((r, file): (Arc<Robot>, MbmFile)) {
    let vars = file.joint_vars(&r).expect("vars");
    // No obstacles: the self pairs decide every verdict.
    let world = CollisionWorld::single(r.clone(), Pose::identity());
    let mut on = SphereChecker::new(&world, 0.0).expect("spheres");
    let mut off = on.clone();
    off.set_node_cull(false);
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    // Segments from a free state to a colliding one: they cross the contact boundary, where
    // inflated spheres touch and plain ones do not.
    let mut states: [Vec<Vec<f64>>; 2] = [Vec::new(), Vec::new()];
    while states[0].len() < 300 || states[1].len() < 300 {
        let q = random_config(&r, &vars, &mut rng);
        let f = off.is_free(&q);
        assert_eq!(on.is_free(&q), f);
        states[usize::from(f)].push(q);
    }
    let (mut free, mut hit) = (0, 0);
    for k in 0..600 {
        let a = states[1][k % 300].clone();
        let b = if k % 2 == 0 {
            states[0][k / 2 % 300].clone()
        } else {
            // A short segment from a free state toward a colliding one.
            let c = &states[0][(k / 2 + 7) % 300];
            a.iter().zip(c).map(|(x, y)| x + 0.15 * (y - x)).collect()
        };
        assert_eq!(on.is_free(&a), off.is_free(&a), "state {k}");
        let v = same_segment_verdicts(&mut on, &mut off, &a, &b, &mut rng, k);
        if v {
            free += 1;
        } else {
            hit += 1;
        }
    }
    assert!(free > 50 && hit > 50, "{free} free, {hit} in collision");
}

#[test]
fn hot_body_first_changes_nothing() {
    // Panda among a bookshelf's boxes and cylinders: motions into the shelves hit a few links
    // again and again, so the hot body is often right and often wrong.
    hot_order_changes_nothing("panda", "bookshelf_tall", 29);
}

#[test]
fn hot_and_warm_bodies_change_nothing_on_two_arms() {
    // Baxter's two arms in a bookshelf: random motions hit one arm or the other, so the hot
    // body (the last hit) and the warm one (the hit before) change from check to check.
    hot_order_changes_nothing("baxter", "bookshelf_tall_both_arms_hard", 31);
}

/// With the hot and warm bodies tested first or every body in tree order, certified motion
/// checks and raked state checks give the same verdicts after the same number of states.
fn hot_order_changes_nothing(robot: &str, set: &str, seed: u64) {
    let Some((r, file)) = mbm(robot) else {
        return;
    };
    let vars = file.joint_vars(&r).expect("vars");
    let set = file.set(set).expect("set");
    let world = set.problems[0].world(r.clone());
    let mut on = SphereChecker::new(&world, 0.0).expect("spheres");
    let mut off = on.clone();
    off.set_hot_first(false);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut free, mut hit) = (0, 0);
    for k in 0..1500 {
        let a = random_config(&r, &vars, &mut rng);
        let c = random_config(&r, &vars, &mut rng);
        let t = [1.0, 0.3, 0.08][k % 3];
        let b: Vec<f64> = a.iter().zip(&c).map(|(x, y)| x + t * (y - x)).collect();
        let v = same_segment_verdicts(&mut on, &mut off, &a, &b, &mut rng, k);
        if v {
            free += 1;
        } else {
            hit += 1;
        }
    }
    assert!(free > 100 && hit > 100, "{free} free, {hit} in collision");
}

#[test]
fn auto_checker_picks_spheres_for_sphere_robots() {
    let (r, file) = twin_problems();
    let world = file.sets[0].problems[0].world(r);
    assert_eq!(AutoChecker::new(&world, 0.0).kind(), "spheres");
}

/// Certified segments (swept-volume bounds) are free as continuous motions: the exact checker
/// finds every state free at a resolution 10× finer than the exact re-check of `bench mbm`, for Panda and
/// Baxter (self-collision pairs on a shared torso included). Certification is not vacuous: most
/// segments that the exact fine check finds free are certified, and segments the exact check
/// finds colliding are never certified. Focused refinement (only what was tight at a
/// sub-interval's ends) certifies every segment the unfocused one does, and nothing colliding.
fn certified_segments_are_free((r, file): (Arc<Robot>, MbmFile), max_inflation: f64) {
    let name = file.robot.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (mut certified, mut exact_free, mut exact_hits) = (0, 0, 0);
    let mut linear_certified = 0;
    for set in &file.sets {
        for p in set.problems.iter().filter(|p| p.valid).take(2) {
            let world = p.world(r.clone());
            let mut sc = SphereChecker::new(&world, 0.0).expect("spheres");
            assert!(sc.certifiable());
            let mut unfocused = sc.clone();
            unfocused.set_focus(false);
            // The linear certificate (speed bounds only), the chord one's alternative.
            let mut linear = sc.clone();
            linear.set_chord(false);
            let mut exact = ExactChecker::new(&world);
            for _ in 0..30 {
                // From the start or a goal (close to obstacles) toward a nearby configuration.
                let from = if rng.random_bool(0.5) {
                    &p.start
                } else {
                    &p.goals[rng.random_range(0..p.goals.len())]
                };
                let a = from.clone();
                let b: Vec<f64> = from
                    .iter()
                    .map(|v| v + rng.random_range(-0.6..0.6))
                    .collect();
                let cert = sc.segment_certified(&a, &b, max_inflation);
                let unfocused_cert = unfocused.segment_certified(&a, &b, max_inflation);
                let linear_cert = linear.segment_certified(&a, &b, max_inflation);
                assert!(
                    cert || !unfocused_cert,
                    "only the unfocused check certifies"
                );
                // Exact states every 0.025° of the largest joint move.
                let dmax = a
                    .iter()
                    .zip(&b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                let n = ((dmax / 0.025f64.to_radians()).ceil() as usize).max(1);
                let free = (0..=n).all(|k| {
                    let t = k as f64 / n as f64;
                    let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect();
                    exact.is_free(&q)
                });
                if cert {
                    certified += 1;
                    assert!(free, "{}[{}]: certified but exact collides", p.set, p.index);
                }
                if linear_cert {
                    linear_certified += 1;
                    assert!(
                        free,
                        "{}[{}]: linear certificate but exact collides",
                        p.set, p.index
                    );
                }
                if free {
                    exact_free += 1;
                } else {
                    exact_hits += 1;
                }
            }
        }
    }
    eprintln!(
        "{name}: {certified} certified ({linear_certified} by the linear certificate), \
         {exact_free} exactly free, {exact_hits} colliding"
    );
    assert!(exact_hits > 0, "no colliding segment drawn");
    assert!(
        certified * 10 >= exact_free * 6 && linear_certified * 10 >= exact_free * 6,
        "{certified} ({linear_certified}) certified of {exact_free} exactly free"
    );
}

/// Segments through states a little short of a contact (bisected on the segment from a free state
/// to a colliding one with the plain spheres), in random directions and lengths: some graze the
/// contact between the certification's states, some miss it, some cross it.
fn grazing_segments(
    sc: &mut SphereChecker,
    free: &[Vec<f64>],
    colliding: &[Vec<f64>],
    vars: &[usize],
    rng: &mut ChaCha8Rng,
    count: usize,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let lerp = |a: &[f64], b: &[f64], t: f64| -> Vec<f64> {
        a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect()
    };
    (0..count)
        .map(|k| {
            let a = &free[k % free.len()];
            let c = &colliding[rng.random_range(0..colliding.len())];
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..30 {
                let mid = 0.5 * (lo + hi);
                if sc.is_free(&lerp(a, c, mid)) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            // A little short of the contact, so that some segments through it miss.
            let q = lerp(a, c, (lo - rng.random_range(0.0..0.05)).max(0.0));
            let len = rng.random_range(0.02..0.4);
            let mut d = vec![0.0; q.len()];
            for &v in vars {
                d[v] = rng.random_range(-len..len);
            }
            let a: Vec<f64> = q.iter().zip(&d).map(|(x, y)| x + y).collect();
            let b: Vec<f64> = q.iter().zip(&d).map(|(x, y)| x - y).collect();
            (a, b)
        })
        .collect()
}

/// Focused refinement (only what was tight at a sub-interval's ends) against a fine discrete
/// check of the plain spheres, on grazing segments with a coarse first pass (large inflation,
/// so contacts between its states are common): whatever it certifies has no colliding state
/// among 2000, it certifies everything the unfocused check does, and the segments are a mix.
fn focused_refinement_misses_nothing(world: &CollisionWorld, r: &Robot, vars: &[usize], seed: u64) {
    let mut sc = SphereChecker::new(world, 0.0).expect("spheres");
    let mut unfocused = sc.clone();
    unfocused.set_focus(false);
    let mut fine = sc.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut states: [Vec<Vec<f64>>; 2] = [Vec::new(), Vec::new()];
    while states[0].len() < 200 || states[1].len() < 200 {
        let q = random_config(r, vars, &mut rng);
        let f = fine.is_free(&q);
        states[usize::from(f)].push(q);
    }
    let segments = grazing_segments(&mut fine, &states[1], &states[0], vars, &mut rng, 1500);
    let (mut certified, mut colliding, mut uncertified_free) = (0, 0, 0);
    for (k, (a, b)) in segments.iter().enumerate() {
        if !fine.is_free(a) {
            continue;
        }
        let cert = sc.segment_certified(a, b, 0.2);
        assert!(
            cert || !unfocused.segment_certified(a, b, 0.2),
            "segment {k}"
        );
        let free = fine.segment_free(a, b, 2000);
        if cert {
            certified += 1;
            assert!(free, "segment {k}: certified, but a state collides");
        }
        colliding += usize::from(!free);
        uncertified_free += usize::from(free && !cert);
    }
    eprintln!("{certified} certified, {colliding} colliding, {uncertified_free} free uncertified");
    assert!(
        certified > 200 && colliding > 200,
        "{certified} {colliding}"
    );
}

#[test]
fn focused_refinement_misses_no_contact() {
    let Some((r, file)) = mbm("panda") else {
        return;
    };
    let vars = file.joint_vars(&r).expect("vars");
    for (i, set) in file.sets.iter().enumerate() {
        let world = set.problems[0].world(r.clone());
        focused_refinement_misses_nothing(&world, &r, &vars, 23 + i as u64);
    }
}

/// The benchmark-only switch that drops the certificate (`bench mbm --uncertified`): the
/// certified checks' first pass visits the same states with plain spheres, so it finds the same
/// collisions and never refines; on grazing segments it accepts motions that pass through a
/// contact between its states, which the certified check never does. The work counts count
/// every certified check and its refinement calls.
#[test]
fn uncertified_switch_checks_the_same_states_and_never_refines() {
    let (r, file) = twin_problems();
    let vars = file.joint_vars(&r).expect("vars");
    let world = file.sets[2].problems[0].world(r.clone());
    let mut sc = SphereChecker::new(&world, 0.0).expect("spheres");
    let mut unc = sc.clone();
    unc.set_uncertified_for_benchmark(true);
    let mut fine = sc.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(43);
    let mut states: [Vec<Vec<f64>>; 2] = [Vec::new(), Vec::new()];
    while states[0].len() < 100 || states[1].len() < 100 {
        let q = random_config(&r, &vars, &mut rng);
        let f = fine.is_free(&q);
        states[usize::from(f)].push(q);
    }
    let segments = grazing_segments(&mut fine, &states[1], &states[0], &vars, &mut rng, 600);
    let (mut calls, mut tight, mut through_contact) = (0u64, 0, 0);
    for (k, (a, b)) in segments.iter().enumerate() {
        if !fine.is_free(a) {
            continue;
        }
        let (c0, u0) = (sc.checks(), unc.checks());
        let screen = sc.segment_screened(a, b, 0.2);
        let plain = unc.segment_screened(a, b, 0.2);
        assert_eq!(
            sc.checks() - c0,
            unc.checks() - u0,
            "segment {k}: other states"
        );
        assert_eq!(
            screen == SegmentScreen::Collides,
            plain == SegmentScreen::Collides,
            "segment {k}"
        );
        assert_ne!(plain, SegmentScreen::Tight, "segment {k}");
        let cert = sc.segment_certified(a, b, 0.2);
        assert!(unc.segment_certified(a, b, 0.2) || !cert, "segment {k}");
        calls += 2;
        tight += usize::from(screen == SegmentScreen::Tight);
        if plain == SegmentScreen::Certified && !fine.segment_free(a, b, 2000) {
            assert!(!cert, "segment {k}: certified through a contact");
            through_contact += 1;
        }
    }
    let (counts, plain_counts) = (sc.certify_counts(), unc.certify_counts());
    assert_eq!(counts.segments, calls);
    assert_eq!(plain_counts.segments, calls);
    assert_eq!(plain_counts.refinements, 0);
    assert!(
        counts.refinements >= tight as u64,
        "{counts:?}, {tight} tight"
    );
    // Seeded: 173 tight, 1 accepted through a contact (measured).
    assert!(
        tight > 20 && through_contact >= 1,
        "{tight} tight, {through_contact} accepted through a contact"
    );
    sc.reset_certify_counts();
    assert_eq!(sc.certify_counts(), CertifyCounts::default());
}

/// The same for self pairs: twin_arms alone (arms and torso, no obstacles).
#[test]
fn focused_refinement_misses_no_self_contact() {
    let (r, file) = twin_problems();
    let vars = file.joint_vars(&r).expect("vars");
    let world = CollisionWorld::single(r.clone(), Pose::identity());
    focused_refinement_misses_nothing(&world, &r, &vars, 31);
}

/// The same for Baxter alone.
#[test]
fn focused_refinement_misses_no_self_contact_on_baxter() {
    let Some((r, file)) = mbm("baxter") else {
        return;
    };
    let vars = file.joint_vars(&r).expect("vars");
    let world = CollisionWorld::single(r.clone(), Pose::identity());
    focused_refinement_misses_nothing(&world, &r, &vars, 31);
}

#[test]
fn twin_arms_certified_segments_are_free() {
    certified_segments_are_free(twin_problems(), 0.04);
}

#[test]
fn panda_certified_segments_are_free() {
    let Some(data) = mbm("panda") else { return };
    certified_segments_are_free(data, 0.04);
}

#[test]
fn baxter_certified_segments_are_free() {
    let Some(data) = mbm("baxter") else { return };
    certified_segments_are_free(data, 0.04);
}

/// At the exact contact boundary (found by bisection with the exact f64 checker to 1e-12 of a
/// segment), the f32 sphere checker still reports the colliding side as colliding: its rounding
/// margin covers the f32 error where it matters most.
fn conservative_at_the_contact_boundary((r, file): (Arc<Robot>, MbmFile), tries: usize) {
    let vars = file.joint_vars(&r).expect("vars");
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let mut boundaries = 0;
    for set in &file.sets {
        for p in set.problems.iter().filter(|p| p.valid).take(3) {
            let world = p.world(r.clone());
            let mut sc = SphereChecker::new(&world, 0.0).expect("spheres");
            let mut exact = ExactChecker::new(&world);
            let full = |q: &[f64]| {
                let mut w = r.zero_config();
                for (i, &v) in vars.iter().enumerate() {
                    w[v] = q[i];
                }
                w
            };
            for _ in 0..tries {
                let a = full(&p.start);
                let b: Vec<f64> = a.iter().map(|v| v + rng.random_range(-1.0..1.0)).collect();
                if exact.is_free(&b) {
                    continue;
                }
                let at = |t: f64| -> Vec<f64> {
                    a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect()
                };
                let (mut lo, mut hi) = (0.0f64, 1.0f64);
                while hi - lo > 1e-12 {
                    let mid = 0.5 * (lo + hi);
                    if exact.is_free(&at(mid)) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let q = at(hi);
                assert!(
                    !sc.is_free(&q),
                    "{}[{}]: exact contact at t = {hi}, spheres free; q = {q:?}",
                    p.set,
                    p.index
                );
                // The 8-lane path (AVX2 + FMA when the CPU has it) is as conservative.
                assert!(
                    sc.any_collides(&[q.as_slice(); 8]),
                    "{}[{}]: exact contact at t = {hi}, 8-lane spheres free; q = {q:?}",
                    p.set,
                    p.index
                );
                boundaries += 1;
            }
        }
    }
    assert!(boundaries > 50, "only {boundaries} boundaries");
}

#[test]
fn twin_arms_spheres_conservative_at_the_contact_boundary() {
    conservative_at_the_contact_boundary(twin_problems(), 50);
}

#[test]
fn panda_spheres_conservative_at_the_contact_boundary() {
    let Some(data) = mbm("panda") else { return };
    conservative_at_the_contact_boundary(data, 20);
}

#[test]
fn baxter_spheres_conservative_at_the_contact_boundary() {
    let Some(data) = mbm("baxter") else { return };
    conservative_at_the_contact_boundary(data, 20);
}
