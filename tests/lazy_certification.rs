//! Lazy certification in RRT-Connect (`RrtConnectSettings::lazy`): tree edges the certified
//! check's first pass accepts are added unproven and certified only on a found path; an edge
//! that fails goes with its subtree. Every returned path must still be fully certified: each
//! segment is re-certified here by a fresh sphere checker, and the path passes the exact
//! checker. Runs on MotionBenchMaker's Panda problems (skipped without the data, see
//! `manyhands::benchmark::mbm_data`).

use std::sync::Arc;
use std::time::Duration;

use manyhands::benchmark::mbm::MbmFile;
use manyhands::benchmark::mbm_data::data_for_test;
use manyhands::collision::{AutoChecker, ExactChecker, SegmentScreen, SphereChecker};
use manyhands::planning::base::range::DerivedSettings;
use manyhands::planning::{RrtConnect, RrtConnectSettings, SpaceValidator, Termination};
use manyhands::Robot;

/// Plans the first `per_set` valid problems of `sets` with `bench mbm`'s settings and the given
/// largest inflation, lazily or not, and checks every path: each segment certified by a fresh
/// sphere checker with the same inflation, and the whole path exactly valid at 0.5°. Returns
/// the states lazy certification removed, summed.
fn solve(sets: &[&str], per_set: usize, certify: f64, lazy: bool) -> u64 {
    let Some(dir) = data_for_test() else {
        return 0;
    };
    let file = MbmFile::load(&dir.join("panda/problems.json")).expect("panda problems");
    let robot = Arc::new(
        Robot::from_files(
            &dir.join("panda/panda_spherized.urdf"),
            Some(&dir.join("panda/panda.srdf")),
        )
        .expect("panda"),
    );
    let vars = file.joint_vars(&robot).expect("joints");
    let mut removed = 0;
    for set in file.sets.iter().filter(|s| sets.contains(&s.name.as_str())) {
        for p in set.problems.iter().filter(|p| p.valid).take(per_set) {
            let world = p.world(robot.clone());
            let space = p.space(&world, &vars).expect("space");
            let derived = DerivedSettings::of(&world, &space).expect("derived settings");
            let settings = RrtConnectSettings {
                range: Some(derived.range),
                certify: Some(certify),
                dynamic_domain: Some(derived.dynamic_domain),
                balance: true,
                revalidate: false,
                lazy,
                ..RrtConnectSettings::default()
            };
            let checker = AutoChecker::new(&world, 0.0);
            assert_eq!(checker.kind(), "spheres");
            let mut planner = RrtConnect::with_checker(space.clone(), &world, checker, settings)
                .expect("planner");
            let mut term = Termination::new().with_time_limit(Duration::from_secs(20));
            let r = planner
                .plan(&p.start, &p.goals, &mut term, 3)
                .unwrap_or_else(|e| panic!("{}[{}]: {e}", set.name, p.index));
            if !lazy {
                assert_eq!(r.stats.lazy_removed, 0);
            }
            removed += r.stats.lazy_removed;
            let mut fresh = SphereChecker::new(&world, 0.0).expect("sphere model");
            let (mut wa, mut wb) = (space.base().to_vec(), space.base().to_vec());
            for seg in r.path.windows(2) {
                space.write_world(&seg[0], &mut wa);
                space.write_world(&seg[1], &mut wb);
                assert!(
                    fresh.segment_certified(&wa, &wb, certify),
                    "{}[{}]: a returned segment is not certified",
                    set.name,
                    p.index
                );
            }
            let mut exact = SpaceValidator::new(
                space.clone(),
                &world,
                ExactChecker::new(&world),
                0.5f64.to_radians(),
                0.005,
            );
            assert_eq!(
                exact.validate_path(&r.path),
                Ok(()),
                "{}[{}]",
                set.name,
                p.index
            );
        }
    }
    removed
}

#[test]
fn lazy_paths_are_fully_certified() {
    solve(&["cage", "bookshelf_thin", "box"], 3, 0.04, true);
}

#[test]
fn eager_paths_are_fully_certified() {
    solve(&["cage"], 2, 0.04, false);
}

/// With a coarse first pass (large inflations, few states per edge) screening accepts edges
/// that collide between its states; lazy certification must catch them on found paths, remove
/// them and still return certified, exactly valid paths.
#[test]
fn failed_lazy_edges_are_removed_and_the_search_goes_on() {
    if data_for_test().is_none() {
        return;
    }
    let removed = solve(&["cage", "bookshelf_small"], 4, 0.3, true);
    assert!(
        removed > 0,
        "no lazily accepted edge failed its certification"
    );
}

/// The screening pass agrees with the full certificate: `Collides` only where the certificate
/// fails, `Certified` only where it holds, and a `Tight` segment certified from its screening
/// record gets the full certificate's verdict.
#[test]
fn screening_is_consistent_with_the_certificate() {
    let Some(dir) = data_for_test() else { return };
    let file = MbmFile::load(&dir.join("panda/problems.json")).expect("panda problems");
    let robot = Arc::new(
        Robot::from_files(
            &dir.join("panda/panda_spherized.urdf"),
            Some(&dir.join("panda/panda.srdf")),
        )
        .expect("panda"),
    );
    let vars = file.joint_vars(&robot).expect("joints");
    let set = file.set("cage").expect("cage");
    let p = set
        .problems
        .iter()
        .find(|p| p.valid)
        .expect("a valid problem");
    let world = p.world(robot.clone());
    let space = p.space(&world, &vars).expect("space");
    let mut sc = SphereChecker::new(&world, 0.0).expect("sphere model");
    let (mut wa, mut wb) = (space.base().to_vec(), space.base().to_vec());
    let mut seen = [0usize; 3];
    let mut x = 0.123f64;
    let mut next = || {
        x = (x * 7.31 + 0.377).fract();
        x
    };
    let lo = space.lower().to_vec();
    let hi = space.upper().to_vec();
    for _ in 0..400 {
        let a: Vec<f64> = (0..lo.len())
            .map(|i| lo[i] + (hi[i] - lo[i]) * next())
            .collect();
        // Short motions from `a` (about an EXTEND step), so that all three verdicts occur.
        let b: Vec<f64> = (0..lo.len())
            .map(|i| (a[i] + 0.6 * (next() - 0.5)).clamp(lo[i], hi[i]))
            .collect();
        if !sc_free(&mut sc, &space, &a, &mut wa) {
            continue;
        }
        space.write_world(&a, &mut wa);
        space.write_world(&b, &mut wb);
        let screened = sc.segment_screened(&wa, &wb, 0.04);
        let record = sc.screened_tight().to_vec();
        let certified = sc.segment_certified(&wa, &wb, 0.04);
        match screened {
            SegmentScreen::Collides => assert!(!certified),
            SegmentScreen::Certified => assert!(certified),
            // Certifying from the screening record (what lazy planners do for path edges)
            // gives the full certificate's verdict.
            SegmentScreen::Tight => assert_eq!(
                sc.segment_certified_screened(&wa, &wb, 0.04, &record),
                certified
            ),
        }
        seen[screened as usize] += 1;
    }
    assert!(seen.iter().all(|&n| n > 0), "verdicts seen: {seen:?}");
}

fn sc_free(
    sc: &mut SphereChecker,
    space: &manyhands::planning::JointSpace,
    q: &[f64],
    w: &mut [f64],
) -> bool {
    use manyhands::collision::CollisionChecker;
    space.write_world(q, w);
    sc.is_free(w)
}
