/// A MotionBenchMaker robot (spherized URDF and SRDF) from the data folder of
/// [`crate::benchmark::mbm_data::data_for_test`]; `None` (the test is skipped) without it.
fn mbm_robot(name: &str) -> Option<std::sync::Arc<crate::Robot>> {
    let dir = crate::benchmark::mbm_data::data_for_test()?.join(name);
    Some(std::sync::Arc::new(
        crate::Robot::from_files(
            &dir.join(format!("{name}_spherized.urdf")),
            Some(&dir.join(format!("{name}.srdf"))),
        )
        .expect("robot"),
    ))
}

/// The sphere checker of `robot` alone at the world origin, without padding.
fn checker_of(robot: &std::sync::Arc<crate::Robot>) -> super::SphereChecker {
    let world = super::CollisionWorld::single(robot.clone(), crate::geometry::Pose::identity());
    super::SphereChecker::new(&world, 0.0).expect("spheres")
}

/// The suite's own sphere robot `tests/robots/twin_arms` (two arms with the Panda's
/// kinematics, its truncated quarter turns included, on a torso).
fn twin_arms() -> std::sync::Arc<crate::Robot> {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/robots");
    std::sync::Arc::new(
        crate::Robot::from_files(
            &dir.join("twin_arms.urdf"),
            Some(&dir.join("twin_arms.srdf")),
        )
        .expect("tests/robots/twin_arms"),
    )
}

/// The node-level cull of a pair group is a bound of every pair in it: over random
/// configurations (8 lanes) and random inflations, whenever the nodes' spheres are apart in
/// every lane, so is every pair's body-level test that the cull skips. Both outcomes
/// occur, and pairs near in some lane occur in culled-free groups.
#[test]
fn node_cull_bounds_every_pair_of_its_group() {
    node_cull_bounds_every_pair(twin_arms());
}

#[test]
fn node_cull_bounds_every_pair_of_its_group_on_baxter() {
    if let Some(r) = mbm_robot("baxter") {
        node_cull_bounds_every_pair(r);
    }
}

fn node_cull_bounds_every_pair(robot: std::sync::Arc<crate::Robot>) {
    use super::*;
    use rand::{Rng, SeedableRng};
    let mut sc = checker_of(&robot);
    assert!(
        sc.pair_group_end.iter().any(|&e| e != 0),
        "{} has pair groups",
        robot.name
    );
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (mut culled, mut kept, mut near_pairs) = (0, 0, 0);
    for _ in 0..300 {
        for (v, lanes) in sc.qv.iter_mut().enumerate() {
            let l = robot.var_limits(v);
            for x in lanes.iter_mut() {
                *x = rng.random_range(l.lower.max(-4.0)..=l.upper.min(4.0)) as f32;
            }
        }
        for x in sc.infl.iter_mut() {
            *x = rng.random_range(0.0..0.05);
        }
        sc.epoch = sc.epoch.wrapping_add(1).max(1);
        for si in 0..sc.steps.len() {
            sc.step::<LANES, false>(si);
        }
        for b in 0..sc.bodies.len() {
            let body = &sc.bodies[b];
            let c = SphereChecker::place::<LANES, false>(&sc.frames[body.node as usize], &body.bc);
            sc.bcw[b] = c;
        }
        for pi in 0..sc.self_pairs.len() {
            let end = sc.pair_group_end[pi] as usize;
            if end == 0 {
                continue;
            }
            let (a, b) = sc.self_pairs[pi];
            let (na, nb) = (sc.bodies[a as usize].node, sc.bodies[b as usize].node);
            let node_near = sc.nodes_near::<LANES, false>(na as usize, nb as usize);
            if node_near {
                kept += 1;
            } else {
                culled += 1;
            }
            for &(a, b) in &sc.self_pairs[pi..end] {
                let (a, b) = (a as usize, b as usize);
                let r = sc.bodies[a].br + sc.bodies[b].br + (sc.infl[a] + sc.infl[b]);
                let m = near_mask::<LANES>(&sc.bcw[a], &sc.bcw[b], r);
                if m != 0 {
                    near_pairs += 1;
                    assert!(
                        node_near,
                        "pair ({a}, {b}) near in lanes {m:b}, nodes culled"
                    );
                }
            }
        }
    }
    assert!(
        culled > 100 && kept > 100 && near_pairs > 100,
        "{culled} {kept} {near_pairs}"
    );
}

/// Quarter-turn and identity origins (Panda's `rpy="±1.57079632679 0 0"`) are recognised,
/// and the kinematics through them (AVX and generic) give the frames of the general
/// product within f32 rounding, over random 8-lane states of arms with the Panda's
/// kinematics.
#[test]
fn specialised_origins_give_the_general_frames() {
    specialised_origins(twin_arms());
}

#[test]
fn specialised_origins_give_the_general_frames_on_panda() {
    if let Some(r) = mbm_robot("panda") {
        specialised_origins(r);
    }
}

fn specialised_origins(robot: std::sync::Arc<crate::Robot>) {
    use super::*;
    use nalgebra::Matrix3;
    use rand::{Rng, SeedableRng};
    // The URDF's truncated π/2 and π/4, as written there.
    #[allow(clippy::approx_constant)]
    let (half_pi, quarter_pi) = (1.57079632679, 0.785398163397);
    let quarter = nalgebra::Rotation3::from_euler_angles(-half_pi, 0.0, 0.0);
    match OriginRot::classify(quarter.matrix()) {
        OriginRot::Permutation(cols) => {
            assert_eq!(cols, [(0, 0), (2, 0x8000_0000), (1, 0)], "x, −z, y")
        }
        k => panic!("{k:?}"),
    }
    let yaw = nalgebra::Rotation3::from_euler_angles(0.0, 0.0, -quarter_pi);
    assert_eq!(OriginRot::classify(yaw.matrix()), OriginRot::General);
    assert_eq!(
        OriginRot::classify(&Matrix3::identity()),
        OriginRot::Identity
    );
    assert_eq!(
        origin_terms(&Vector3::new(-0.0825, 3e-17, 0.384)),
        ([-0.0825, 0.0, 0.384], 0b101)
    );
    let mut fast = checker_of(&robot);
    let (mut perms, mut sparse) = (0, 0);
    for s in &fast.steps[1..] {
        perms += usize::from(matches!(s.rot_kind, OriginRot::Permutation(_)));
        sparse += usize::from(s.t_terms != 0b111);
    }
    assert!(
        perms >= 6 && sparse >= 6,
        "{perms} quarter turns, {sparse} sparse"
    );
    let mut general = fast.clone();
    for s in &mut general.steps[1..] {
        s.rot_kind = OriginRot::General;
        s.t_terms = 0b111;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut worst = 0.0f32;
    for _ in 0..200 {
        for (v, lanes) in fast.qv.iter_mut().enumerate() {
            let l = robot.var_limits(v);
            for x in lanes.iter_mut() {
                *x = rng.random_range(l.lower.max(-4.0)..=l.upper.min(4.0)) as f32;
            }
        }
        general.qv.clone_from(&fast.qv);
        let mut avx = fast.clone();
        for si in 0..fast.steps.len() {
            fast.step::<LANES, false>(si);
            general.step::<LANES, false>(si);
        }
        // No obstacles: every step is computed before the self pairs.
        #[cfg(target_arch = "x86_64")]
        if avx.avx2 {
            // SAFETY: AVX2 + FMA are present (checked at construction).
            unsafe { avx.run8_avx2() };
        }
        for (si, (f, g)) in fast.frames.iter().zip(&general.frames).enumerate() {
            for k in 0..12 {
                for l in 0..LANES {
                    worst = worst.max((f[k][l] - g[k][l]).abs());
                    if avx.avx2 {
                        let a = avx.frames[si][k][l];
                        assert!((a - g[k][l]).abs() < 1e-5, "step {si} entry {k}");
                    }
                }
            }
        }
    }
    assert!(worst < 1e-5, "worst {worst:e}");
}

/// A refinement's focus holds every id tight at either end of its sub-interval, once, and
/// nothing else.
#[test]
fn focus_holds_what_is_tight_at_either_end() {
    use super::certified::{focus_of_lanes, focus_of_states};
    use super::SELF_PAIR;
    let states = [(2, 4), (3, 1), (3, 4), (4, 7), (5, SELF_PAIR | 2), (9, 1)];
    let mut out = vec![99];
    focus_of_states(&states, 3, 4, &mut out);
    assert_eq!(out, [99, 1, 4, 7], "state 3 and state 4, 4 once");
    out.clear();
    focus_of_states(&states, 4, 5, &mut out);
    assert_eq!(out, [7, SELF_PAIR | 2]);
    out.clear();
    focus_of_states(&states, 1, 2, &mut out);
    assert_eq!(out, [4], "only the right end tight");
    out.clear();
    focus_of_states(&states, 6, 7, &mut out);
    assert!(out.is_empty());
    let log = [
        (3, 0b0000_0001),
        (5, 0b0100_0000),
        (SELF_PAIR | 1, 0b1000_0000),
    ];
    out.clear();
    focus_of_lanes(&log, 0, 1, &mut out);
    assert_eq!(out, [3]);
    out.clear();
    focus_of_lanes(&log, 5, 1, &mut out);
    assert_eq!(out, [5], "only the right end tight");
    out.clear();
    focus_of_lanes(&log, 6, 1, &mut out);
    assert_eq!(out, [5, SELF_PAIR | 1]);
    out.clear();
    focus_of_lanes(&log, 2, 1, &mut out);
    assert!(out.is_empty());
    // Two sub-intervals at once: every id tight at any of their three states.
    out.clear();
    focus_of_states(&states, 2, 4, &mut out);
    assert_eq!(out, [4, 1, 7]);
    out.clear();
    focus_of_lanes(&log, 5, 2, &mut out);
    assert_eq!(out, [5, SELF_PAIR | 1]);
    out.clear();
    focus_of_lanes(&log, 1, 2, &mut out);
    assert!(out.is_empty());
}

/// Runs of sub-intervals to refine are grouped two at a time, a lone one alone, each needed
/// one exactly once and nothing else.
#[test]
fn refinements_pair_runs() {
    use super::certified::pair_runs;
    let groups = |n: usize, need: &[usize]| {
        let mut g = Vec::new();
        pair_runs(n, |i| need.contains(&i), |i, span| g.push((i, span)));
        g
    };
    assert_eq!(groups(7, &[]), []);
    assert_eq!(groups(7, &[3]), [(3, 1)]);
    assert_eq!(groups(7, &[2, 3]), [(2, 2)]);
    assert_eq!(groups(7, &[0, 1, 2]), [(0, 2), (2, 1)]);
    assert_eq!(groups(7, &[1, 2, 3, 4, 6]), [(1, 2), (3, 2), (6, 1)]);
    assert_eq!(groups(7, &[5, 6]), [(5, 2)]);
    assert_eq!(groups(1, &[0]), [(0, 1)]);
}

#[test]
fn sincos_f32_is_accurate() {
    let mut worst: f64 = 0.0;
    for i in 0..=200_000 {
        let x = -10.0 + 20.0 * i as f64 / 200_000.0;
        let (s, c) = super::sincos_lanes::<1, false>(&[x as f32]);
        let (s, c) = (s[0], c[0]);
        let xr = x as f32 as f64;
        worst = worst
            .max((s as f64 - xr.sin()).abs())
            .max((c as f64 - xr.cos()).abs());
    }
    assert!(worst < 5e-7, "worst {worst:e}");
}

/// The AVX2 kinematics step ([`SphereChecker::step_avx`]) gives the generic FMA step's frames
/// bit for bit, with the quarter-turn origins as classified, with every origin general, and
/// with the translations' zero terms kept.
#[cfg(target_arch = "x86_64")]
#[test]
fn avx_step_is_the_generic_step_bit_for_bit() {
    use super::*;
    use rand::{Rng, SeedableRng};
    let robot = twin_arms();
    let mut sc = checker_of(&robot);
    if !sc.avx2 {
        return;
    }
    let mut general = sc.clone();
    for s in &mut general.steps[1..] {
        s.rot_kind = OriginRot::General;
        s.t_terms = 0b111;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for mut model in [sc.clone(), general] {
        for _ in 0..100 {
            for (v, lanes) in model.qv.iter_mut().enumerate() {
                let l = robot.var_limits(v);
                for x in lanes.iter_mut() {
                    *x = rng.random_range(l.lower.max(-4.0)..=l.upper.min(4.0)) as f32;
                }
            }
            sc = model.clone();
            for si in 0..model.steps.len() {
                model.step_lanes::<LANES, true>(si);
                // SAFETY: AVX2 + FMA are present (checked above).
                unsafe { sc.step_avx(si) };
            }
            for (f, g) in sc.frames.iter().zip(&model.frames) {
                for k in 0..12 {
                    for l in 0..LANES {
                        assert_eq!(f[k][l].to_bits(), g[k][l].to_bits());
                    }
                }
            }
        }
    }
}

/// The 8-lane AVX2 check (`body_env_avx`, `pair_spheres_avx`, `step_avx`) finds a collision
/// exactly when the generic 8-lane check does and, when there is none, logs the same tight
/// lanes per body and self pair: batches of 8 states along random segments, with random
/// inflations. The suite's two-arm robot alone (self pairs), and the Panda in a cage and
/// Baxter in a bookshelf when the MotionBenchMaker data is there. (Written to guard changes
/// to the order and placement of the AVX2 tests, which must keep every verdict.)
#[test]
fn avx_checks_equal_the_generic_checks() {
    use crate::collision::CollisionWorld;
    use crate::geometry::Pose;
    let r = twin_arms();
    let world = CollisionWorld::single(r.clone(), Pose::identity());
    avx_checks_equal_the_generic_checks_in(&world, &r, 5);
    for (name, set) in [
        ("panda", "cage"),
        ("baxter", "bookshelf_tall_both_arms_hard"),
    ] {
        let Some(r) = mbm_robot(name) else { return };
        let Some(dir) = crate::benchmark::mbm_data::data_for_test() else {
            return;
        };
        let file = crate::benchmark::mbm::MbmFile::load(&dir.join(name).join("problems.json"))
            .expect("problems");
        let set = file.set(set).expect("set");
        let world = set.problems[0].world(r.clone());
        avx_checks_equal_the_generic_checks_in(&world, &r, 6);
    }
}

fn avx_checks_equal_the_generic_checks_in(
    world: &crate::collision::CollisionWorld,
    r: &crate::Robot,
    seed: u64,
) {
    use super::*;
    use rand::{Rng, SeedableRng};
    let mut avx = SphereChecker::new(world, 0.0).expect("spheres");
    if !avx.avx2 {
        return;
    }
    let mut generic = avx.clone();
    generic.avx2 = false;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (mut hits, mut free, mut tight) = (0, 0, 0);
    for k in 0..3000 {
        let mut config = || -> Vec<f64> {
            (0..r.dof())
                .map(|v| {
                    let l = r.var_limits(v);
                    rng.random_range(l.lower.max(-4.0)..=l.upper.min(4.0))
                })
                .collect()
        };
        let (a, c) = (config(), config());
        let t = [1.0, 0.3, 0.1][k % 3];
        let b: Vec<f64> = a.iter().zip(&c).map(|(x, y)| x + t * (y - x)).collect();
        let ts: [f64; LANES] = std::array::from_fn(|l| l as f64 / (LANES - 1) as f64);
        let h = [0.0, 0.02, 0.2][k % 3];
        let lens: Vec<f64> = avx
            .seg_len
            .iter()
            .map(|_| rng.random_range(0.0..1.0))
            .collect();
        for sc in [&mut avx, &mut generic] {
            for ((d, x), y) in sc.seg_dq.iter_mut().zip(&a).zip(&b) {
                *d = (y - x).abs();
            }
            sc.seg_len.copy_from_slice(&lens);
            sc.seg_epoch = sc.seg_epoch.wrapping_add(1).max(1);
            sc.set_inflation(h);
            sc.load_lanes(&a, &b, &ts);
        }
        let hit = avx.collides8();
        assert_eq!(hit, generic.collides8(), "batch {k}");
        if hit {
            hits += 1;
        } else {
            free += 1;
            let (mut x, mut y) = (avx.tight_log.clone(), generic.tight_log.clone());
            x.sort_unstable();
            y.sort_unstable();
            assert_eq!(x, y, "batch {k}");
            tight += usize::from(!x.is_empty());
        }
    }
    for sc in [&mut avx, &mut generic] {
        sc.infl.iter_mut().for_each(|i| *i = 0.0);
        sc.pair_scale = 0.0;
    }
    assert!(
        hits > 100 && free > 100 && tight > 10,
        "{hits} hits, {free} free, {tight} with tight lanes"
    );
    // The chord certificate's calls: the same verdicts; the same tight sub-intervals but where
    // a ball grazes an obstacle within the FMA rounding of the two paths.
    let (mut hits, mut free, mut tight, mut differ) = (0, 0, 0, 0);
    for k in 0..3000 {
        let mut config = || -> Vec<f64> {
            (0..r.dof())
                .map(|v| {
                    let l = r.var_limits(v);
                    rng.random_range(l.lower.max(-4.0)..=l.upper.min(4.0))
                })
                .collect()
        };
        let (a, c) = (config(), config());
        let t = [1.0, 0.3, 0.1][k % 3];
        let b: Vec<f64> = a.iter().zip(&c).map(|(x, y)| x + t * (y - x)).collect();
        let ts: [f64; LANES] = std::array::from_fn(|l| l as f64 / (LANES - 1) as f64);
        for sc in [&mut avx, &mut generic] {
            for ((d, x), y) in sc.seg_dq.iter_mut().zip(&a).zip(&b) {
                *d = (y - x).abs();
            }
            sc.segment_accelerations();
            sc.set_chord_allowance(1.0 / (LANES - 1) as f64);
            sc.load_lanes(&a, &b, &ts);
        }
        let hit = avx.chord8(NO_FOCUS, NO_FOCUS, 0).is_some();
        assert_eq!(
            hit,
            generic.chord8(NO_FOCUS, NO_FOCUS, 0).is_some(),
            "chord batch {k}"
        );
        if hit {
            hits += 1;
        } else {
            free += 1;
            let (mut x, mut y) = (avx.tight_log.clone(), generic.tight_log.clone());
            x.sort_unstable();
            y.sort_unstable();
            differ += usize::from(x != y);
            tight += usize::from(!x.is_empty());
        }
    }
    for sc in [&mut avx, &mut generic] {
        sc.end_segment();
    }
    assert!(
        hits > 100 && free > 100 && tight > 10 && differ * 100 <= free,
        "chord: {hits} hits, {free} free, {tight} with tight sub-intervals, {differ} differ"
    );
}

/// The certified checks' speed bounds (`var_w` per body, `pair_w` per self pair, from the
/// distances of the sphere centres to the joint axes, see `SphereChecker::new`) bound how far
/// every sphere centre travels, and how much every pair's centre-to-centre distance changes
/// (the pair certificate's quantity: joints above the common ancestor move both rigidly),
/// along straight joint-space segments: measured over 400 states per segment with the checker's own
/// kinematics. The largest ratio of travel to bound is reported, so a bound that is not one
/// fails and one far from tight shows.
#[test]
fn speed_bounds_bound_the_travel_of_every_sphere_centre() {
    speed_bounds_bound_travel(twin_arms());
}

#[test]
fn speed_bounds_bound_the_travel_of_every_sphere_centre_on_panda() {
    if let Some(r) = mbm_robot("panda") {
        speed_bounds_bound_travel(r);
    }
}

fn speed_bounds_bound_travel(robot: std::sync::Arc<crate::Robot>) {
    use super::*;
    use rand::{Rng, SeedableRng};
    let mut sc = checker_of(&robot);
    let dof = sc.qv.len();
    let stride = sc.seg_len.len();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    // World positions of every sphere centre at the 8 lanes' configurations.
    let centres = |sc: &mut SphereChecker| -> Vec<[[f32; LANES]; 3]> {
        for si in 0..sc.steps.len() {
            sc.step::<LANES, false>(si);
        }
        let mut out = vec![[[0.0f32; LANES]; 3]; sc.spheres.len()];
        for body in &sc.bodies {
            let f = &sc.frames[body.node as usize];
            for s in body.spheres.0 as usize..body.spheres.1 as usize {
                let p = sc.spheres[s];
                out[s] = SphereChecker::place::<LANES, false>(f, &[p[0], p[1], p[2]]);
            }
        }
        out
    };
    let sphere_body: Vec<usize> = (0..sc.spheres.len())
        .map(|s| {
            sc.bodies
                .iter()
                .position(|b| (b.spheres.0 as usize..b.spheres.1 as usize).contains(&s))
                .expect("every sphere belongs to a body")
        })
        .collect();
    const STATES: usize = 400;
    let (mut worst, mut worst_pair) = (0.0f64, 0.0f64);
    for _ in 0..60 {
        let a: Vec<f64> = (0..dof)
            .map(|v| {
                let l = robot.var_limits(v);
                rng.random_range(l.lower.max(-3.0)..=l.upper.min(3.0))
            })
            .collect();
        let scale = rng.random_range(0.05..1.0);
        let b: Vec<f64> = (0..dof)
            .map(|v| {
                let l = robot.var_limits(v);
                let x = a[v] + scale * rng.random_range(-2.0..2.0);
                x.clamp(l.lower.max(-3.0), l.upper.min(3.0))
            })
            .collect();
        // Σ_v |Δq_v| · w_v with `w_v = w[v · step + i]` (`var_w` is variable-major with the
        // bodies' stride, `pair_w` pair-major with one entry per variable).
        let bound = |w: &[f64], step: usize, i: usize| -> f64 {
            (0..dof)
                .map(|v| (b[v] - a[v]).abs() * w[v * step + i])
                .sum()
        };
        let mut travel = vec![0.0f64; sc.spheres.len()];
        // Per self pair, per pair of their spheres (row-major), the total change of distance.
        let mut pair_travel: Vec<Vec<f64>> = sc
            .self_pairs
            .iter()
            .map(|&(ba, bb)| {
                let (ra, rb) = (
                    sc.bodies[ba as usize].spheres,
                    sc.bodies[bb as usize].spheres,
                );
                vec![0.0; ((ra.1 - ra.0) * (rb.1 - rb.0)) as usize]
            })
            .collect();
        let mut prev: Option<Vec<[[f32; LANES]; 3]>> = None;
        for chunk in 0..STATES.div_ceil(LANES) {
            let ts: [f64; LANES] = std::array::from_fn(|l| {
                ((chunk * LANES + l).min(STATES - 1)) as f64 / (STATES - 1) as f64
            });
            for (v, lanes) in sc.qv.iter_mut().enumerate() {
                for (x, t) in lanes.iter_mut().zip(&ts) {
                    *x = (a[v] + (b[v] - a[v]) * t) as f32;
                }
            }
            let now = centres(&mut sc);
            // Consecutive states: lane l − 1 → l, and the previous chunk's last lane → lane 0.
            let at = |c: &[[f32; LANES]; 3], l: usize| {
                nalgebra::Vector3::new(c[0][l] as f64, c[1][l] as f64, c[2][l] as f64)
            };
            for (s, c) in now.iter().enumerate() {
                for l in 0..LANES {
                    let before = match (l, &prev) {
                        (0, Some(p)) => at(&p[s], LANES - 1),
                        (0, None) => continue,
                        _ => at(c, l - 1),
                    };
                    travel[s] += (at(c, l) - before).norm();
                }
            }
            for (pi, &(ba, bb)) in sc.self_pairs.iter().enumerate() {
                let (ra, rb) = (
                    &sc.bodies[ba as usize].spheres,
                    &sc.bodies[bb as usize].spheres,
                );
                let (i0, j0, nj) = (ra.0 as usize, rb.0 as usize, (rb.1 - rb.0) as usize);
                for i in ra.0 as usize..ra.1 as usize {
                    for j in rb.0 as usize..rb.1 as usize {
                        let len = &mut pair_travel[pi][(i - i0) * nj + (j - j0)];
                        for l in 0..LANES {
                            let rel =
                                |c: &Vec<[[f32; LANES]; 3]>, l: usize| at(&c[i], l) - at(&c[j], l);
                            let before = match (l, &prev) {
                                (0, Some(p)) => rel(p, LANES - 1),
                                (0, None) => continue,
                                _ => rel(&now, l - 1),
                            };
                            *len += (rel(&now, l).norm() - before.norm()).abs();
                        }
                    }
                }
            }
            prev = Some(now);
        }
        for (s, &len) in travel.iter().enumerate() {
            let lim = bound(&sc.var_w, stride, sphere_body[s]);
            assert!(
                len <= lim * (1.0 + 1e-4) + 1e-5,
                "{}: sphere {s} travels {len} m, bound {lim} m",
                robot.name
            );
            if lim > 1e-3 {
                worst = worst.max(len / lim);
            }
        }
        for (pi, lens) in pair_travel.iter().enumerate() {
            let len = lens.iter().fold(0.0f64, |m, &x| m.max(x));
            let lim = bound(&sc.pair_w[pi * dof..], 1, 0);
            assert!(
                len <= lim * (1.0 + 1e-4) + 1e-5,
                "{}: self pair {pi} moves {len} m apart, bound {lim} m",
                robot.name
            );
            if lim > 1e-3 {
                worst_pair = worst_pair.max(len / lim);
            }
        }
    }
    eprintln!(
        "{}: largest travel / bound {worst:.3} (spheres), {worst_pair:.3} (self pairs)",
        robot.name
    );
    assert!(
        worst > 0.3,
        "{}: bounds far from every measured travel",
        robot.name
    );
}

/// A robot of the generality suite (`benchmarks/generality/NAME/`, shipped with the
/// repository).
fn generality_robot(dir: &str, name: &str) -> std::sync::Arc<crate::Robot> {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("benchmarks/generality")
        .join(dir);
    std::sync::Arc::new(
        crate::Robot::from_files(
            &dir.join(format!("{name}_spherized.urdf")),
            Some(&dir.join(format!("{name}_spherized.srdf"))),
        )
        .expect("generality robot"),
    )
}

/// The chord certificate's acceleration bounds (`chord.rs`) bound how far every sphere centre,
/// every body's bounding-sphere centre and every node's bounding-sphere centre strays from the
/// chord between two states of a straight joint-space segment: `A h² / 8` on sub-intervals of
/// length `h` (the whole segment, a seventh and a 49th of it), measured at 64 states per
/// sub-interval with the checker's own kinematics, on arms with long links (UR5-like), an
/// offset wrist and quarter-turn origins (two arms with the Panda's kinematics), and a
/// prismatic lift (Fetch-like). The largest ratio of measured deviation to bound is reported:
/// a bound that is not one fails, one far from tight shows.
#[test]
fn acceleration_bounds_bound_every_centre_s_distance_from_its_chord() {
    for robot in [
        twin_arms(),
        generality_robot("ur5like", "ur5like"),
        generality_robot("fetchlike", "fetchlike"),
    ] {
        acceleration_bounds_bound_chord_distance(robot);
    }
}

fn acceleration_bounds_bound_chord_distance(robot: std::sync::Arc<crate::Robot>) {
    use super::*;
    use nalgebra::Vector3;
    use rand::{Rng, SeedableRng};
    let mut sc = checker_of(&robot);
    let dof = sc.qv.len();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
    // Per point (sphere centres, then body centres, then node centres): its bound's index into
    // `seg_acc` (bodies) or `node_acc` (nodes, offset by the body count).
    let nb = sc.bodies.len();
    let mut owner: Vec<usize> = Vec::new();
    for (b, body) in sc.bodies.iter().enumerate() {
        owner.extend(std::iter::repeat_n(
            b,
            (body.spheres.1 - body.spheres.0) as usize,
        ));
    }
    owner.extend(0..nb);
    let nodes: Vec<usize> = (0..sc.steps.len())
        .filter(|&n| sc.node_anchor[n].0 != u32::MAX)
        .collect();
    owner.extend(nodes.iter().map(|&n| nb + n));
    // World positions of every point at the 8 lanes' configurations.
    let points = |sc: &mut SphereChecker| -> Vec<[[f32; LANES]; 3]> {
        for si in 0..sc.steps.len() {
            sc.step::<LANES, false>(si);
        }
        let mut out = Vec::new();
        for body in &sc.bodies {
            let f = &sc.frames[body.node as usize];
            for s in body.spheres.0 as usize..body.spheres.1 as usize {
                let p = sc.spheres[s];
                out.push(SphereChecker::place::<LANES, false>(f, &[p[0], p[1], p[2]]));
            }
        }
        for body in &sc.bodies {
            let f = &sc.frames[body.node as usize];
            out.push(SphereChecker::place::<LANES, false>(f, &body.bc));
        }
        for &n in &nodes {
            let s = sc.node_sphere[n];
            out.push(SphereChecker::place::<LANES, false>(
                &sc.frames[n],
                &[s[0], s[1], s[2]],
            ));
        }
        out
    };
    let at = |c: &[[f32; LANES]; 3], l: usize| {
        Vector3::new(c[0][l] as f64, c[1][l] as f64, c[2][l] as f64)
    };
    const STATES: usize = 64;
    let mut worst = 0.0f64;
    for _ in 0..40 {
        let a: Vec<f64> = (0..dof)
            .map(|v| {
                let l = robot.var_limits(v);
                rng.random_range(l.lower.max(-3.0)..=l.upper.min(3.0))
            })
            .collect();
        let scale = rng.random_range(0.05..1.0);
        let b: Vec<f64> = (0..dof)
            .map(|v| {
                let l = robot.var_limits(v);
                let x = a[v] + scale * rng.random_range(-1.5..1.5);
                x.clamp(l.lower.max(-3.0), l.upper.min(3.0))
            })
            .collect();
        for (d, (x, y)) in sc.seg_dq.iter_mut().zip(a.iter().zip(&b)) {
            *d = (y - x).abs();
        }
        let amax = sc.segment_accelerations();
        sc.all_accelerations();
        // The call count's bound (over the nodes no descendant dominates) covers every body's.
        let mut largest = sc.seg_acc[..nb].iter().fold(0.0f64, |m, &x| m.max(x));
        // And equals the bound over every node (pruning leaves the maximum unchanged).
        for (b, body) in sc.bodies.iter().enumerate() {
            let [_, c, e, _, p, _] = sc.acc_node[body.node as usize];
            largest = largest.max((sc.acc_static_body[b].0 * c + e + p) * (1.0 + 1e-5));
        }
        assert!(
            largest <= amax * (1.0 + 1e-9),
            "{}: a body's bound {largest} exceeds the call count's {amax}",
            robot.name
        );
        let bounds: Vec<f64> = sc
            .seg_acc
            .iter()
            .take(nb)
            .chain(&sc.node_acc)
            .copied()
            .collect();
        for h in [1.0, 1.0 / 7.0, 1.0 / 49.0] {
            let t0 = rng.random_range(0.0..=1.0 - h);
            // States t0 + h·k/(STATES − 1): the chord's ends are the first and last.
            let mut track: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); owner.len()];
            for chunk in 0..STATES / LANES {
                for (v, lanes) in sc.qv.iter_mut().enumerate() {
                    for (l, x) in lanes.iter_mut().enumerate() {
                        let t = t0 + h * (chunk * LANES + l) as f64 / (STATES - 1) as f64;
                        *x = (a[v] + (b[v] - a[v]) * t) as f32;
                    }
                }
                for (k, p) in points(&mut sc).iter().enumerate() {
                    track[k].extend((0..LANES).map(|l| at(p, l)));
                }
            }
            for (k, ps) in track.iter().enumerate() {
                let (p0, p1) = (ps[0], ps[STATES - 1]);
                let chord = p1 - p0;
                let len2 = chord.norm_squared();
                let off = ps
                    .iter()
                    .map(|p| {
                        let s = if len2 > 0.0 {
                            ((p - p0).dot(&chord) / len2).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                        (p - (p0 + chord * s)).norm()
                    })
                    .fold(0.0f64, f64::max);
                let lim = bounds[owner[k]] * h * h / 8.0;
                assert!(
                    off <= lim * (1.0 + 1e-3) + 2e-6,
                    "{}: point {k} strays {off} m from its chord, bound {lim} m (h = {h})",
                    robot.name
                );
                if lim > 1e-4 {
                    worst = worst.max(off / lim);
                }
            }
        }
    }
    eprintln!(
        "{}: largest distance from the chord / bound {worst:.3}",
        robot.name
    );
    assert!(
        worst > 0.05,
        "{}: bounds far from every measured distance",
        robot.name
    );
}

/// On an arm with long links the chord certificate proves free segments with fewer checked
/// states than the linear one (the reason it is the default), and both agree on which
/// range-length segments of the UR5-like arm in an empty cell are free.
#[test]
fn chord_certificate_checks_fewer_states_than_the_linear_one_on_long_links() {
    use rand::{Rng, SeedableRng};
    let robot = generality_robot("ur5like", "ur5like");
    let mut chord = checker_of(&robot);
    let mut linear = chord.clone();
    linear.set_chord(false);
    let dof = chord.qv.len();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let (mut both, mut disagree) = (0, 0);
    let (c0, l0) = (chord.checks, linear.checks);
    for _ in 0..200 {
        let a: Vec<f64> = (0..dof).map(|_| rng.random_range(-3.0..3.0)).collect();
        let d: Vec<f64> = (0..dof).map(|_| rng.random_range(-1.0..1.0)).collect();
        let n = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        let b: Vec<f64> = a.iter().zip(&d).map(|(x, y)| x + 0.96 * y / n).collect();
        let (x, y) = (
            chord.segment_certified(&a, &b, 0.04),
            linear.segment_certified(&a, &b, 0.04),
        );
        both += usize::from(x && y);
        disagree += usize::from(x != y);
    }
    let (c, l) = (chord.checks - c0, linear.checks - l0);
    eprintln!("ur5like: chord {c} states, linear {l}; {both} free, {disagree} differ");
    assert!(both > 50, "{both} segments free");
    assert!(disagree * 20 <= both, "{disagree} verdicts differ");
    assert!(c * 5 <= l * 4, "chord {c} states, linear {l}");
}

/// The checker tests exactly the world's checked pairs: with two robots (the second's links
/// indexed after the first's), fixed bodies within every link's reach and pairs the world
/// allows, each body's obstacle list and the self pairs equal what `CollisionWorld::pairs`
/// names (set-up indexes bodies densely instead of hashing them).
#[test]
fn checker_tests_exactly_the_world_s_checked_pairs() {
    use super::*;
    use crate::collision::world::{PlacedRobot, StaticBody, StaticKind};
    use crate::geometry::{Geometry, Pose, Shape};
    let robot = generality_robot("ur5like", "ur5like");
    let mut world = CollisionWorld::single(robot.clone(), Pose::identity());
    world.robots.push(PlacedRobot {
        name: "second".into(),
        robot: robot.clone(),
        base: Pose::translation(0.3, 0.0, 0.0),
        offset: robot.dof(),
    });
    // Within every link's reach from either base (set-up drops a fixed body no configuration
    // brings a link to).
    for (k, y) in [0.05, 0.0, -0.05].into_iter().enumerate() {
        world.statics.push(StaticBody {
            name: format!("ball{k}"),
            kind: StaticKind::Obstacle,
            pose: Pose::translation(0.15, y, 0.0),
            shapes: vec![Geometry {
                origin: Pose::identity(),
                shape: Shape::Sphere { radius: 0.05 },
            }],
        });
    }
    let links = robot.links.len();
    // A link of each robot allowed to touch a ball, and one pair across the robots.
    world.allow(
        BodyId::Link {
            robot: 1,
            link: links - 2,
        },
        BodyId::Static(1),
    );
    world.allow(
        BodyId::Link {
            robot: 0,
            link: links - 2,
        },
        BodyId::Static(2),
    );
    world.allow(
        BodyId::Link {
            robot: 0,
            link: links - 3,
        },
        BodyId::Link {
            robot: 1,
            link: links - 3,
        },
    );
    let pairs = world.pairs();
    let sc = SphereChecker::new(&world, 0.0).expect("spheres");
    let mut statics_seen = 0;
    for body in &sc.bodies {
        let listed: std::collections::BTreeSet<u32> = sc.body_obstacles
            [body.obstacles.0 as usize..body.obstacles.1 as usize]
            .iter()
            .map(|&oi| sc.obstacle_static[oi as usize])
            .collect();
        let named: std::collections::BTreeSet<u32> = pairs
            .iter()
            .filter(|p| p.0 == body.id)
            .filter_map(|p| match p.1 {
                BodyId::Static(s) => Some(s as u32),
                _ => None,
            })
            .collect();
        assert_eq!(listed, named, "{:?}", body.id);
        statics_seen += listed.len();
    }
    // Both robots' bodies met every ball but the ones allowed.
    assert_eq!(statics_seen, 3 * sc.bodies.len() - 2);
    let id = |b: u32| sc.bodies[b as usize].id;
    let mut tested: Vec<(BodyId, BodyId)> =
        sc.self_pairs.iter().map(|&(a, b)| (id(a), id(b))).collect();
    let mut named: Vec<(BodyId, BodyId)> = pairs
        .iter()
        .filter(|p| !matches!(p.1, BodyId::Static(_)))
        .filter(|p| sc.bodies.iter().any(|b| b.id == p.0) && sc.bodies.iter().any(|b| b.id == p.1))
        .map(|&(a, b)| {
            let pos = |x: BodyId| sc.bodies.iter().position(|b| b.id == x);
            if pos(a) <= pos(b) {
                (a, b)
            } else {
                (b, a)
            }
        })
        .collect();
    let key = |p: &(BodyId, BodyId)| format!("{p:?}");
    tested.sort_by_key(key);
    named.sort_by_key(key);
    assert_eq!(tested, named);
    assert!(!tested.contains(&(
        BodyId::Link {
            robot: 0,
            link: links - 3
        },
        BodyId::Link {
            robot: 1,
            link: links - 3
        },
    )));
}

/// The self pairs' second test (`chord_within_origin`, AVX and generic): a lane is marked
/// exactly when the chord from its difference to the next lane's comes within `r` of the
/// origin, against the distance computed in f64 and by sampling the chord; zero-length chords
/// (equal lanes) are their point's distance. Lanes within 1e-5 m of the boundary are not
/// judged (f32 rounding).
#[test]
fn chord_within_origin_is_the_chord_s_distance_from_the_origin() {
    use super::{Lane, LANES};
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let (mut judged, mut near, mut far) = (0, 0, 0);
    for k in 0..4000 {
        let mut d: [Lane; 3] = [[0.0; LANES]; 3];
        for l in 0..LANES {
            for c in 0..3 {
                d[c][l] = rng.random_range(-0.3f32..0.3);
            }
            if k % 4 == 0 && l % 2 == 1 {
                for c in 0..3 {
                    d[c][l] = d[c][l - 1];
                }
            }
        }
        let r: f32 = rng.random_range(0.0..0.35);
        let generic = super::chord::chord_within_origin(&d, r);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: AVX2 and FMA are present (checked above).
            let avx = unsafe {
                super::avx8::chord_within_origin(
                    [
                        super::avx8::load1(&d[0]),
                        super::avx8::load1(&d[1]),
                        super::avx8::load1(&d[2]),
                    ],
                    r,
                )
            };
            assert_eq!(avx & 0x7f, generic & 0x7f, "case {k}");
        }
        for l in 0..LANES - 1 {
            let p = |j: usize| [0, 1, 2].map(|c| f64::from(d[c][j]));
            let (a, b) = (p(l), p(l + 1));
            let e = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let ee = e.iter().map(|x| x * x).sum::<f64>();
            let de = (0..3).map(|c| a[c] * e[c]).sum::<f64>();
            let s = if ee > 0.0 {
                (-de / ee).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let dist = (0..3)
                .map(|c| (a[c] + s * e[c]).powi(2))
                .sum::<f64>()
                .sqrt();
            let sampled = (0..=1000)
                .map(|i| {
                    let t = f64::from(i) / 1000.0;
                    (0..3)
                        .map(|c| (a[c] + t * e[c]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(dist <= sampled + 1e-12 && sampled - dist < 1e-3, "case {k}");
            if (dist - f64::from(r)).abs() < 1e-5 {
                continue;
            }
            judged += 1;
            let marked = generic & (1 << l) != 0;
            assert_eq!(
                marked,
                dist < f64::from(r),
                "case {k} lane {l}: {dist} vs {r}"
            );
            near += usize::from(marked);
            far += usize::from(!marked);
        }
    }
    assert!(
        near > 1000 && far > 1000,
        "{judged} judged: {near} near, {far} far"
    );
}

/// Two spheres at a constant distance turning about a common axis (a UR5's base sphere and
/// the sphere at its upper arm's origin: 2.4 mm apart at every configuration) are proven
/// apart by the chord's distance from the origin in the first pass: a motion that turns the
/// shoulder by a radian and lifts the arm is certified without one refinement call, where the
/// ball about the chord's midpoint alone (its half chord ≈ 10 mm) needed refinement; and a
/// motion that brings a third sphere into the first is refused — also one whose checked states
/// are all free, the crossing lying between two of them, which only the tight pair's chord
/// (through the origin) sends to refinement.
#[test]
fn a_pair_at_constant_distance_is_certified_without_refinement() {
    let urdf = r#"<?xml version="1.0"?>
<robot name="shoulder_pair">
  <link name="base"><collision><geometry><sphere radius="0.08"/></geometry></collision></link>
  <link name="shoulder"/>
  <link name="upper_arm"><collision><geometry><sphere radius="0.08"/></geometry></collision></link>
  <link name="slider"><collision><geometry><sphere radius="0.01"/></geometry></collision></link>
  <joint name="pan" type="revolute"><parent link="base"/><child link="shoulder"/>
    <origin xyz="0 0 0.089159"/><axis xyz="0 0 1"/><limit lower="-3.14" upper="3.14" effort="1" velocity="1"/></joint>
  <joint name="lift" type="revolute"><parent link="shoulder"/><child link="upper_arm"/>
    <origin xyz="0 0.13585 0"/><axis xyz="0 1 0"/><limit lower="-3.14" upper="3.14" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="slider"/>
    <origin xyz="0.5 0 0"/><axis xyz="-1 0 0"/><limit lower="0" upper="2" effort="1" velocity="1"/></joint>
</robot>"#;
    let srdf = r#"<?xml version="1.0"?>
<robot name="shoulder_pair">
  <disable_collisions link1="base" link2="shoulder" reason="Adjacent"/>
  <disable_collisions link1="shoulder" link2="upper_arm" reason="Adjacent"/>
  <disable_collisions link1="slider" link2="upper_arm" reason="Never"/>
</robot>"#;
    let robot = std::sync::Arc::new(
        crate::Robot::from_strings(urdf, Some(srdf), std::path::Path::new(".")).expect("robot"),
    );
    let mut c = checker_of(&robot);
    assert_eq!(c.qv.len(), 3);
    let pan = robot.var("pan").expect("pan");
    let lift = robot.var("lift").expect("lift");
    let slide = robot.var("slide").expect("slide");
    let q = |p: f64, l: f64, s: f64| {
        let mut v = vec![0.0; 3];
        v[pan] = p;
        v[lift] = l;
        v[slide] = s;
        v
    };
    let (a, b) = (q(-0.5, 0.0, 0.0), q(0.5, 0.5, 0.0));
    c.reset_certify_counts();
    assert!(c.segment_certified(&a, &b, 0.04), "the pair stays apart");
    assert_eq!(c.certify_counts().refinements, 0, "no refinement needed");
    // The slider's sphere ends inside the base's sphere: refused.
    assert!(!c.segment_certified(&q(0.0, 0.0, 0.0), &q(0.0, 0.0, 0.5), 0.04));
    assert!(!c.segment_certified(&q(0.0, 0.0, 0.3), &q(0.0, 0.0, 0.5), 0.04));
    // It passes through it between two checked states (x = 0.1, then -0.1, 0.2 apart; they
    // touch within 0.09 of the base's centre): both ends free, the motion refused.
    let (s0, s1) = (q(0.0, 0.0, 0.4), q(0.0, 0.0, 1.8));
    assert!(c.segment_certified(&s0, &s0, 0.04) && c.segment_certified(&s1, &s1, 0.04));
    c.reset_certify_counts();
    assert!(
        !c.segment_certified(&s0, &s1, 0.04),
        "the crossing is found"
    );
    assert!(c.certify_counts().refinements > 0, "found by refinement");
}
