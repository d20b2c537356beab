//! Reachability grids (paper 000 §II-B): deterministic parallel build, versioned file refused on
//! other parameters / chain / kinematics / corruption, lookups consistent with FK.

#[path = "common/tmp.rs"]
mod tmp;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use manyhands::cache_tier::{MemoryTier, REACH};
use manyhands::collision::{CollisionChecker, CollisionWorld, FastChecker};
use manyhands::geometry::Pose;
use manyhands::kinematics::Chain;
use manyhands::model::load_robot_dir;
use manyhands::reachability::{
    slice_svg, GridCache, GridParams, GridRecipe, ReachError, ReachabilityGrid, SliceAxes,
};
use manyhands::Robot;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn armar() -> Arc<Robot> {
    let lib =
        load_robot_dir(&Path::new(env!("CARGO_MANIFEST_DIR")).join("robots")).expect("robots");
    lib.get("armar").expect("armar").clone()
}

fn params(robot: &Robot, group: &str, samples: u64, seed: u64) -> GridParams {
    let chain = Chain::from_group(robot, group).expect("chain");
    GridParams::auto(robot, &chain, 0.08, 6, samples, seed).expect("params")
}

fn tmp(name: &str) -> PathBuf {
    tmp::run_root().join(format!("manyhands-reach-{}-{name}", std::process::id()))
}

#[test]
fn build_is_deterministic_and_thread_count_independent() {
    let robot = armar();
    let p = params(&robot, "right_arm", 60_000, 5);
    let a = ReachabilityGrid::build(&robot, "right_arm", &p, &|_| {}).expect("build");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let b = one
        .install(|| ReachabilityGrid::build(&robot, "right_arm", &p, &|_| {}))
        .expect("build");
    assert_eq!(a.data(), b.data());
    assert_eq!(a.stats(), b.stats());
    let s = a.stats();
    assert_eq!(s.samples, 60_000);
    assert!(s.free > 30_000 && s.free < 60_000, "free {}", s.free);
    assert!(s.filled > 1000);
    // Another seed gives another grid.
    let c = ReachabilityGrid::build(
        &robot,
        "right_arm",
        &params(&robot, "right_arm", 60_000, 6),
        &|_| {},
    )
    .expect("build");
    assert_ne!(a.data(), c.data());
}

#[test]
fn lookups_agree_with_fk_and_collision() {
    let robot = armar();
    let p = params(&robot, "right_arm", 300_000, 1);
    let g = ReachabilityGrid::build(&robot, "right_arm", &p, &|_| {}).expect("build");
    let chain = Chain::from_group(&robot, "right_arm").expect("chain");
    let mut checker = FastChecker::new(&CollisionWorld::single(robot.clone(), Pose::identity()));
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut q = robot.named_config("home").expect("home");
    let (mut n, mut hit) = (0, 0);
    while n < 2000 {
        for &v in &chain.vars {
            let l = robot.var_limits(v);
            q[v] = rng.random_range(l.lower..=l.upper);
        }
        if !checker.is_free(&q) {
            continue;
        }
        n += 1;
        let tip = chain.tip_pose(&robot, &q);
        assert!(
            g.cell_of(&tip).is_some(),
            "a reachable TCP pose lies outside the extents"
        );
        if g.probability(&tip) > 0.0 {
            hit += 1;
        }
    }
    // New samples fall mostly into cells the build filled.
    assert!(hit as f64 > 0.6 * n as f64, "{hit} of {n}");
    // Far away: probability 0; the best cell has probability 1.
    let far = Pose::translation(5.0, 0.0, 0.0);
    assert_eq!(g.probability(&far), 0.0);
    assert!(g.data().iter().any(|&e| e == g.max_entry()) && g.max_entry() > 0);
}

/// Single and batched lookups (which answer empty cells from the occupancy bitmap) give the
/// raw entry of the pose's cell / the largest entry, at poses in filled, empty and outside cells.
fn lookups_read_the_entries(g: &ReachabilityGrid) {
    use manyhands::kinematics::randomized::ReachabilityMap;
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let p = g.params().clone();
    let (mut filled, mut empty, mut outside) = (0, 0, 0);
    let mut poses = Vec::new();
    for i in 0..40_000 {
        let pos = nalgebra::Vector3::from_fn(|k, _| {
            // A margin beyond the extents gives poses outside.
            rng.random_range(p.min[k] - 0.1..p.max[k] + 0.1)
        });
        let pose = Pose::from_parts(
            pos.into(),
            manyhands::kinematics::dual_arm::random_rotation(&mut rng),
        );
        let want = match g.cell_of(&pose) {
            None => {
                outside += 1;
                0.0
            }
            Some(c) => {
                let e = g.data()[c];
                if e > 0 {
                    filled += 1;
                } else {
                    empty += 1;
                }
                e as f64 / g.max_entry() as f64
            }
        };
        assert_eq!(g.probability(&pose), want, "pose {i}");
        poses.push((pose, want));
    }
    // The batched lookup, with the poses given relative to a frame.
    let frame = Pose::translation(0.01, -0.02, 0.03);
    let tcps: Vec<Pose> = poses.iter().map(|(q, _)| frame.inverse() * q).collect();
    let mut out = vec![f64::NAN; tcps.len()];
    ReachabilityMap::probabilities(g, &frame, &tcps, &mut out);
    for (k, (t, o)) in tcps.iter().zip(&out).enumerate() {
        assert_eq!(*o, g.probability(&(frame * t)), "batched lookup {k}");
    }
    assert!(
        filled > 0 && empty > 0 && outside > 0,
        "{filled} {empty} {outside}"
    );
}

/// The lookup's angle bins are those of nalgebra's roll-pitch-yaw (URDF convention) binned
/// over [−π, π) / [−π/2, π/2) (at gimbal lock the pitch bin only); away from bin edges they must
/// agree exactly.
#[test]
fn cell_angles_are_the_urdf_rpy_bins() {
    let robot = armar();
    for bins in [6u32, 8, 5] {
        let chain = Chain::from_group(&robot, "right_arm").expect("chain");
        let p = GridParams::auto(&robot, &chain, 0.2, bins, 1000, 1).expect("params");
        let g = ReachabilityGrid::build(&robot, "right_arm", &p, &|_| {}).expect("build");
        let b = bins as f64;
        let bin = |a: f64, lo: f64, span: f64| -> Option<usize> {
            let x = (a - lo) / span * b;
            // Skip poses within 1e-9 of an edge (rounding may go either way there).
            if (x - x.round()).abs() < 1e-9 {
                return None;
            }
            Some((x.floor().max(0.0) as usize).min(bins as usize - 1))
        };
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let centre = nalgebra::Vector3::from_fn(|k, _| g.cell_centre(k, 0));
        let mut checked = 0;
        for i in 0..20_000 {
            let rot = if i % 10 == 0 {
                // Gimbal lock: pitch exactly ±π/2.
                let pitch = if i % 20 == 0 { 0.5 } else { -0.5 } * std::f64::consts::PI;
                nalgebra::UnitQuaternion::from_euler_angles(rng.random_range(-3.0..3.0), pitch, 0.3)
            } else {
                manyhands::kinematics::dual_arm::random_rotation(&mut rng)
            };
            let pose = Pose::from_parts(centre.into(), rot);
            let (r, pi, y) = rot.euler_angles();
            let pi_ = std::f64::consts::PI;
            let (Some(br), Some(bp), Some(by)) = (
                bin(r, -pi_, 2.0 * pi_),
                bin(pi, -0.5 * pi_, pi_),
                bin(y, -pi_, 2.0 * pi_),
            ) else {
                continue;
            };
            let c = g.cell_coords(&pose).expect("inside");
            if pi.cos() < 1e-6 {
                // At (or within rounding of) gimbal lock roll and yaw are not determined.
                assert_eq!(c[4], bp, "pitch {pi}, {bins} bins");
                continue;
            }
            assert_eq!(&c[3..], &[br, bp, by], "rpy ({r}, {pi}, {y}), {bins} bins");
            checked += 1;
        }
        assert!(checked > 15_000);
    }
}

#[test]
fn file_roundtrip_and_refusals() {
    let robot = armar();
    let p = params(&robot, "left_arm", 20_000, 2);
    let g = ReachabilityGrid::build(&robot, "left_arm", &p, &|_| {}).expect("build");
    let f = tmp("left.reach");
    g.save(&f).expect("save");
    let back = ReachabilityGrid::load(&f, &robot, "left_arm", Some(&p)).expect("load");
    assert_eq!(back.data(), g.data());
    assert_eq!(back.params(), g.params());
    assert_eq!(back.stats().free, g.stats().free);
    lookups_read_the_entries(&g);
    lookups_read_the_entries(&back);

    // Built with other parameters: refused with a clear error.
    let mut other = p.clone();
    other.resolution = 0.05;
    let e = ReachabilityGrid::load(&f, &robot, "left_arm", Some(&other)).expect_err("refused");
    assert!(matches!(e, ReachError::ParamsMismatch { .. }), "{e}");
    assert!(e.to_string().contains("resolution"), "{e}");
    let mut other = p.clone();
    other.samples += 1;
    let e = ReachabilityGrid::load(&f, &robot, "left_arm", Some(&other)).expect_err("refused");
    assert!(e.to_string().contains("samples"), "{e}");

    // Another chain.
    let e = ReachabilityGrid::load(&f, &robot, "right_arm", None).expect_err("refused");
    assert!(
        matches!(
            e,
            ReachError::Mismatch {
                what: "chain group",
                ..
            }
        ),
        "{e}"
    );

    // Changed kinematics of the chain (elbow moved by 1 cm).
    let mut changed = (*robot).clone();
    let j = changed.joint("left_elbow").expect("joint");
    changed.joints[j].origin.translation.z -= 0.01;
    let e = ReachabilityGrid::load(&f, &changed, "left_arm", None).expect_err("refused");
    assert!(matches!(e, ReachError::KinematicsChanged { .. }), "{e}");
    // A change outside the chain does not matter.
    let mut outside = (*robot).clone();
    let j = outside.joint("right_elbow").expect("joint");
    outside.joints[j].origin.translation.z -= 0.01;
    ReachabilityGrid::load(&f, &outside, "left_arm", None).expect("other arm changed: still valid");

    // Another robot name.
    let mut renamed = (*robot).clone();
    renamed.name = "other".into();
    let e = ReachabilityGrid::load(&f, &renamed, "left_arm", None).expect_err("refused");
    assert!(
        matches!(e, ReachError::Mismatch { what: "robot", .. }),
        "{e}"
    );

    // Truncated, flipped byte, wrong version, not a grid file.
    let bytes = std::fs::read(&f).expect("read");
    let t = tmp("bad.reach");
    std::fs::write(&t, &bytes[..bytes.len() / 2]).expect("write");
    let e = ReachabilityGrid::load(&t, &robot, "left_arm", None).expect_err("refused");
    assert!(matches!(e, ReachError::Corrupt { .. }), "{e}");
    let mut flipped = bytes.clone();
    let k = bytes.len() - 100;
    flipped[k] ^= 0x5a;
    std::fs::write(&t, &flipped).expect("write");
    let e = ReachabilityGrid::load(&t, &robot, "left_arm", None).expect_err("refused");
    assert!(matches!(e, ReachError::Corrupt { .. }), "{e}");
    let mut v2 = bytes.clone();
    v2[8] = 99;
    std::fs::write(&t, &v2).expect("write");
    let e = ReachabilityGrid::load(&t, &robot, "left_arm", None).expect_err("refused");
    assert!(matches!(e, ReachError::Version { found: 99, .. }), "{e}");
    std::fs::write(&t, b"hello world, not a grid").expect("write");
    let e = ReachabilityGrid::load(&t, &robot, "left_arm", None).expect_err("refused");
    assert!(matches!(e, ReachError::BadMagic { .. }), "{e}");
    let e = ReachabilityGrid::load(&tmp("missing.reach"), &robot, "left_arm", None)
        .expect_err("refused");
    assert!(matches!(e, ReachError::Io { .. }), "{e}");
    let _ = std::fs::remove_file(&f);
    let _ = std::fs::remove_file(&t);
}

#[test]
fn invalid_parameters_are_errors() {
    let robot = armar();
    let chain = Chain::from_group(&robot, "right_arm").expect("chain");
    assert!(GridParams::auto(&robot, &chain, 0.0, 8, 10, 1).is_err());
    assert!(GridParams::auto(&robot, &chain, f64::NAN, 8, 10, 1).is_err());
    let mut p = GridParams::auto(&robot, &chain, 0.1, 8, 10, 1).expect("params");
    p.rot_bins = 0;
    assert!(ReachabilityGrid::build(&robot, "right_arm", &p, &|_| {}).is_err());
    let p = GridParams::auto(&robot, &chain, 0.1, 8, 10, 1).expect("params");
    let e = ReachabilityGrid::build(&robot, "no_such_group", &p, &|_| {}).expect_err("no chain");
    assert!(matches!(e, ReachError::NoChain { .. }));
}

#[test]
fn svg_slice_has_cells() {
    let robot = armar();
    let p = params(&robot, "right_arm", 30_000, 4);
    let g = ReachabilityGrid::build(&robot, "right_arm", &p, &|_| {}).expect("build");
    // Slice through the shoulder height (torso frame z = 0.45 − 0.3).
    let svg = slice_svg(
        &g,
        &SliceAxes {
            normal: 2,
            at: 0.15,
            max: false,
        },
    );
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.matches("<rect").count() > 20, "few cells drawn");
}

/// Two grid caches with their own folders and one shared tier (two server replicas): the
/// first builds the grid and publishes it, the second fetches it instead of building; an entry
/// of the tier that does not load (damaged) is rebuilt, not served, and replaced.
#[test]
fn grid_caches_sharing_a_tier_build_a_grid_once() {
    let robot = armar();
    let recipe = GridRecipe {
        resolution: 0.08,
        rot_bins: 6,
        samples: 20_000,
        seed: 3,
    };
    let dirs = [tmp("tier-1"), tmp("tier-2"), tmp("tier-3")];
    for d in &dirs {
        let _ = std::fs::remove_dir_all(d);
    }
    let tier = Arc::new(MemoryTier::new());
    let counts = |t: &MemoryTier| (t.fetches(), t.misses(), t.publishes(), t.replaces());
    let a = GridCache::new(Some(dirs[0].clone())).with_tier(tier.clone());
    let ga = a.get(&robot, "left_arm", recipe).expect("built");
    assert_eq!(counts(&tier), (0, 1, 1, 0));
    let names = tier.names(REACH);
    assert_eq!(names.len(), 1, "{names:?}");
    let name = &names[0];
    assert_eq!(
        tier.get(REACH, name).unwrap(),
        std::fs::read(dirs[0].join(name)).unwrap()
    );
    // In memory: the tier is not asked.
    assert!(Arc::ptr_eq(
        &a.get(&robot, "left_arm", recipe).unwrap(),
        &ga
    ));
    assert_eq!(counts(&tier), (0, 1, 1, 0));

    // "Process 2": an empty folder, the same tier (set on a cache already shared).
    let b = Arc::new(GridCache::new(Some(dirs[1].clone())));
    assert!(b.set_tier(tier.clone()));
    assert!(!b.set_tier(tier.clone()), "a tier is set once");
    let gb = b.get(&robot, "left_arm", recipe).expect("fetched");
    assert_eq!(counts(&tier), (1, 1, 1, 0), "fetched, not built");
    assert_eq!(gb.data(), ga.data());
    assert_eq!(gb.params(), ga.params());
    assert_eq!(gb.stats().free, ga.stats().free);
    assert!(dirs[1].join(name).exists());

    // A damaged entry (one cell flipped: the checksum refuses it) is rebuilt and replaced.
    let mut bytes = tier.get(REACH, name).unwrap();
    let n = bytes.len();
    bytes[n - 20] ^= 0xff;
    tier.insert(REACH, name, bytes);
    let c = GridCache::new(Some(dirs[2].clone())).with_tier(tier.clone());
    let gc = c.get(&robot, "left_arm", recipe).expect("rebuilt");
    assert_eq!(counts(&tier), (2, 1, 1, 1));
    assert_eq!(gc.data(), ga.data());
    assert_eq!(
        tier.get(REACH, name).unwrap(),
        std::fs::read(dirs[0].join(name)).unwrap()
    );
    for d in &dirs {
        let _ = std::fs::remove_dir_all(d);
    }
}
