//! The super graph of paper 003 §V-A (elementary Visibility-PRM roadmaps of torso + each arm of
//! justin, composed) and its online queries with lazy revalidation (§V-B), on a small scene of
//! this test folder (`tests/data/justin_table.json`: a table, a vase, a block). Small node
//! counts keep every test at a few seconds.

mod common;

use std::sync::Arc;

use manyhands::cache_tier::{MemoryTier, ROADMAPS};
use manyhands::collision::{
    CollisionWorld, ExactChecker, FastChecker, MotionValidator, StaticBody, StaticKind,
};
use manyhands::geometry::{Geometry, Pose, Shape};
use manyhands::kinematics::forward;
use manyhands::model::{load_robot_dir, Robot, Scene};
use manyhands::planning::planners::roadmap_cache::{
    load_or_build, load_super_graph, save_super_graph, RoadmapFileError, RoadmapKey, RoadmapSource,
};
use manyhands::planning::planners::roadmap_query::{
    attach_at_link, prm_star_k, query_learning, query_super_graph, LearnedGraph, RoadmapPath,
    RoadmapQuerySettings,
};
use manyhands::planning::planners::super_graph::{
    build_super_graph, roadmap_world, Decomposition, SuperGraph, SuperGraphParams,
};
use manyhands::planning::planners::visibility_prm::VisibilityPrmSettings;
use manyhands::planning::{space_checker, JointSpace, PlannerRng, Termination};
use rand::{Rng, SeedableRng};

use common::root;

fn scene() -> Scene {
    let lib = load_robot_dir(&root().join("robots")).expect("robots");
    Scene::from_file(&root().join("tests/data/justin_table.json"), &lib).expect("scene")
}

struct Setup {
    world: CollisionWorld,
    dec: Decomposition,
    base: Vec<f64>,
}

fn setup() -> Setup {
    let s = scene();
    let world = CollisionWorld::from_scene(&s);
    let dec = Decomposition::from_groups(&world, 0, "torso", ["right_arm", "left_arm"])
        .expect("decomposition");
    let base = CollisionWorld::start_config(&s);
    Setup { world, dec, base }
}

fn params(seed: u64) -> SuperGraphParams {
    SuperGraphParams {
        prm: VisibilityPrmSettings {
            max_nodes: 8,
            max_failures: 30,
            max_samples: 3_000,
            seed,
        },
        ..SuperGraphParams::default()
    }
}

/// The graph without its timing statistics.
fn shape(g: &SuperGraph) -> impl PartialEq + std::fmt::Debug + '_ {
    (
        &g.nodes,
        &g.edges,
        [&g.elementary[0].nodes, &g.elementary[1].nodes],
        [&g.elementary[0].edges, &g.elementary[1].edges],
    )
}

fn build(s: &Setup, p: &SuperGraphParams) -> SuperGraph {
    build_super_graph(&s.world, &s.dec, &s.base, p, &mut Termination::new()).expect("build")
}

/// Exact checker at 0.5° / 5 mm per step on every segment, plus the fast checker's
/// certificate of each continuous segment, plus joint limits.
fn assert_certified_and_exactly_free(world: &CollisionWorld, r: &RoadmapPath) {
    common::assert_exactly_free(world, &r.space, &r.path);
    let mut fast = FastChecker::new(world);
    for (k, w) in r.world_path.windows(2).enumerate() {
        assert!(
            fast.motion_certified(&w[0], &w[1]),
            "segment {k} not certified"
        );
    }
    let mut exact = ExactChecker::new(world);
    let mut mv = MotionValidator::new(world, ExactChecker::new(world), 0.5f64.to_radians(), 0.005);
    assert!(manyhands::collision::CollisionChecker::is_free(
        &mut exact,
        &r.world_path[0]
    ));
    assert!(mv.is_path_valid(&r.world_path));
}

/// A collision-free world configuration of the super space drawn with `seed`.
fn free_goal(world: &CollisionWorld, space: &JointSpace, seed: u64) -> Vec<f64> {
    let mut c = space_checker(world, space);
    let mut rng = PlannerRng::seed_from_u64(seed);
    for _ in 0..10_000 {
        let q: Vec<f64> = (0..space.dim())
            .map(|k| space.lower()[k] + (space.upper()[k] - space.lower()[k]) * rng.random::<f64>())
            .collect();
        let w = space.to_world(&q);
        if manyhands::collision::CollisionChecker::is_free(&mut c, &w) {
            return w;
        }
    }
    panic!("no free goal");
}

#[test]
fn decomposition_from_justins_groups() {
    let s = setup();
    let r = &s.world.robots[0].robot;
    assert_eq!(s.dec.common.len(), 3);
    assert_eq!(s.dec.parts[0].len(), 7);
    assert_eq!(s.dec.parts[1].len(), 7);
    // The right part moves the right hand's links, not the left's nor the torso's.
    let palm = r.link("right_palm").unwrap();
    assert!(s.dec.part_links[0].contains(&palm));
    assert!(!s.dec.part_links[1].contains(&palm));
    assert!(!s.dec.part_links[0].contains(&r.link("chest").unwrap()));
    // Bad groups are refused, naming them.
    let e = Decomposition::from_groups(&s.world, 0, "torso", ["right_arm", "nope"]).unwrap_err();
    assert!(e.to_string().contains("nope"), "{e}");
    let e =
        Decomposition::from_groups(&s.world, 0, "torso", ["right_arm", "right_arm"]).unwrap_err();
    assert!(e.to_string().contains("share"), "{e}");
    // A part overlapping another.
    let e =
        Decomposition::from_groups(&s.world, 0, "torso", ["both_arms", "left_arm"]).unwrap_err();
    assert!(e.to_string().contains("share"), "{e}");
}

#[test]
fn super_edges_only_where_both_elementary_links_exist_and_the_motion_is_free() {
    let s = setup();
    let g = build(&s, &params(3));
    assert!(g.nodes.len() > 20 && !g.edges.is_empty(), "{:?}", g.stats);
    let rw = roadmap_world(&s.world);
    let space = g.space(&rw, s.base.clone()).unwrap();
    let mut full = FastChecker::new(&rw);
    // Every elementary edge is certified in its own world (the other part ignored).
    for k in 0..2 {
        let wk = s.dec.elementary_world(&rw, k);
        let esp = JointSpace::new(&wk, &s.dec.elementary_vars(k), s.base.clone()).unwrap();
        let mut fk = FastChecker::new(&wk);
        for &(a, b) in &g.elementary[k].edges {
            let (qa, qb) = (
                esp.to_world(&g.elementary[k].nodes[a as usize]),
                esp.to_world(&g.elementary[k].nodes[b as usize]),
            );
            assert!(fk.motion_certified(&qa, &qb), "elementary {k} edge {a}-{b}");
        }
    }
    // Nodes: free in the whole roadmap world (both arms, torso, obstacles).
    for (i, n) in g.nodes.iter().enumerate() {
        assert!(
            manyhands::collision::CollisionChecker::is_free(&mut full, &space.to_world(&n.q)),
            "node {i}"
        );
    }
    // Edge ⇔ elementary nodes linked in both roadmaps and the whole motion free.
    let (mut candidates, mut disagree) = (0, 0);
    for x in 0..g.nodes.len() as u32 {
        for y in x + 1..g.nodes.len() as u32 {
            let (nx, ny) = (&g.nodes[x as usize], &g.nodes[y as usize]);
            let linked = (0..2).all(|k| g.elementary_linked(k, nx.from[k], ny.from[k]));
            if !linked {
                assert!(!g.has_edge(x, y), "edge {x}-{y} without elementary links");
                continue;
            }
            candidates += 1;
            let free = full.motion_certified(&space.to_world(&nx.q), &space.to_world(&ny.q));
            if g.has_edge(x, y) {
                assert!(free, "edge {x}-{y} not free in the whole roadmap world");
            } else if free {
                // Refused by the build's pair-restricted check yet certified by a checker of
                // the whole world: their swept-volume bounds differ (frozen vs. all joints).
                disagree += 1;
            }
        }
    }
    assert!(candidates > g.edges.len(), "some candidate must be refused");
    // Not asserted (known gap, see the branch report): some refused candidates are certified
    // by the whole-world checker.
    eprintln!(
        "{disagree} of {} refused candidates certified free by the whole-world checker",
        candidates - g.edges.len()
    );
}

#[test]
fn roadmap_files_are_refused_for_another_robot_scene_or_parameters() {
    let s = setup();
    let p = params(1);
    let dir = common::tmp::run_root().join(format!("manyhands-roadmap-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut term = Termination::new();
    let (g, file, src) =
        load_or_build(Some(&dir), None, &s.world, &s.dec, &s.base, &p, &mut term).unwrap();
    assert_eq!(src, RoadmapSource::Built);
    let file = file.unwrap();
    assert!(file.exists());
    let (g2, _, src2) =
        load_or_build(Some(&dir), None, &s.world, &s.dec, &s.base, &p, &mut term).unwrap();
    assert_eq!(src2, RoadmapSource::Loaded);
    assert_eq!(shape(&g), shape(&g2));
    let key = RoadmapKey::of(&s.world, &s.dec, &s.base, &p).unwrap();
    assert_eq!(load_super_graph(&file, &key).unwrap(), g2);
    let refused = |k: &RoadmapKey| match load_super_graph(&file, k) {
        Err(RoadmapFileError::Mismatch { what, .. }) => what,
        other => panic!("not refused: {:?}", other.map(|g| g.nodes.len())),
    };
    // Parameters: another seed, node count, or base configuration.
    let k = RoadmapKey::of(&s.world, &s.dec, &s.base, &params(2)).unwrap();
    assert_eq!(refused(&k), "parameters");
    let mut base = s.base.clone();
    base[s.dec.parts[1][3]] += 0.1;
    let k = RoadmapKey::of(&s.world, &s.dec, &base, &p).unwrap();
    assert_eq!(refused(&k), "parameters");
    // Scene: an obstacle moved by 1 cm. A free object moved is not part of the roadmap world.
    let mut w = s.world.clone();
    let t = w.statics.iter().position(|b| b.name == "table").unwrap();
    w.statics[t].pose.translation.vector.x += 0.01;
    let k = RoadmapKey::of(&w, &s.dec, &s.base, &p).unwrap();
    assert_eq!(refused(&k), "scene");
    let mut w = s.world.clone();
    let b = w.statics.iter().position(|b| b.name == "block").unwrap();
    w.statics[b].pose.translation.vector.x += 0.01;
    assert_eq!(RoadmapKey::of(&w, &s.dec, &s.base, &p).unwrap(), key);
    // Robot: one joint limit changed.
    let mut r: Robot = (*s.world.robots[0].robot).clone();
    let j = r.vars[s.dec.parts[0][1]];
    r.joints[j].limits.upper -= 0.01;
    let mut w = s.world.clone();
    w.robots[0].robot = Arc::new(r);
    let k = RoadmapKey::of(&w, &s.dec, &s.base, &p).unwrap();
    assert_eq!(refused(&k), "robot");
    // A changed file on disk under the old name is rebuilt, not served.
    save_super_graph(&build(&s, &params(2)), &k, &file).unwrap();
    let (g3, _, src3) =
        load_or_build(Some(&dir), None, &s.world, &s.dec, &s.base, &p, &mut term).unwrap();
    assert_eq!(src3, RoadmapSource::Built);
    assert_eq!(shape(&g3), shape(&g));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Two processes with their own roadmap folders and one shared tier (two server replicas):
/// the first builds the roadmap and publishes it, the second loads it from the tier instead of
/// building; an entry of the tier that does not load (truncated) is rebuilt and replaced.
#[test]
fn roadmaps_are_built_once_by_processes_sharing_a_tier() {
    let s = setup();
    let p = params(3);
    let dirs: Vec<_> = (1..=3)
        .map(|i| {
            let d = common::tmp::run_root()
                .join(format!("manyhands-roadmap-tier-{}-{i}", std::process::id()));
            let _ = std::fs::remove_dir_all(&d);
            d
        })
        .collect();
    let tier = MemoryTier::new();
    let counts = |t: &MemoryTier| (t.fetches(), t.misses(), t.publishes(), t.replaces());
    let mut term = Termination::new();
    let mut run = |dir: &std::path::Path| {
        load_or_build(
            Some(dir),
            Some(&tier),
            &s.world,
            &s.dec,
            &s.base,
            &p,
            &mut term,
        )
        .unwrap()
    };
    let (g1, f1, src) = run(&dirs[0]);
    assert_eq!(src, RoadmapSource::Built);
    let f1 = f1.unwrap();
    let name = f1.file_name().unwrap().to_str().unwrap().to_string();
    assert_eq!(counts(&tier), (0, 1, 1, 0));
    assert_eq!(tier.names(ROADMAPS), [name.as_str()]);

    // "Process 2": an empty folder, the same tier.
    let (g2, f2, src) = run(&dirs[1]);
    assert_eq!(src, RoadmapSource::Loaded);
    assert_eq!(counts(&tier), (1, 1, 1, 0), "fetched, not built");
    assert_eq!(shape(&g2), shape(&g1));
    let key = RoadmapKey::of(&s.world, &s.dec, &s.base, &p).unwrap();
    assert_eq!(load_super_graph(&f1, &key).unwrap(), g2);
    assert!(f2.unwrap().exists());
    // Now in its folder: the tier is not asked again.
    assert_eq!(run(&dirs[1]).2, RoadmapSource::Loaded);
    assert_eq!(counts(&tier), (1, 1, 1, 0));

    // A truncated entry is not served: rebuilt (the same graph) and replaced.
    let bytes = tier.get(ROADMAPS, &name).unwrap();
    tier.insert(ROADMAPS, &name, bytes[..bytes.len() / 2].to_vec());
    let (g3, f3, src) = run(&dirs[2]);
    assert_eq!(src, RoadmapSource::Built);
    assert_eq!(shape(&g3), shape(&g1));
    assert_eq!(counts(&tier), (2, 1, 1, 1));
    assert_eq!(
        tier.get(ROADMAPS, &name).unwrap(),
        std::fs::read(f3.unwrap()).unwrap()
    );
    for d in &dirs {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn build_and_queries_are_deterministic_per_seed() {
    let s = setup();
    let a = build(&s, &params(5));
    let b = build(&s, &params(5));
    assert_eq!(shape(&a), shape(&b));
    let c = build(&s, &params(6));
    assert_ne!(a.elementary, c.elementary);
    let space = a.space(&s.world, s.base.clone()).unwrap();
    let goal = free_goal(&s.world, &space, 11);
    let st = RoadmapQuerySettings::default();
    let q = |seed| {
        query_super_graph(
            &a,
            &s.world,
            &s.base,
            &goal,
            &st,
            &mut Termination::new(),
            seed,
        )
        .expect("query")
    };
    let (p1, p2) = (q(1), q(1));
    assert_eq!(p1.path, p2.path);
}

/// Justin's right TCP link and the right hand's links (allowed to touch what it holds).
fn right_hand(world: &CollisionWorld, dec: &Decomposition) -> (usize, Vec<usize>) {
    let r = &world.robots[0].robot;
    (r.link("right_tcp").unwrap(), dec.part_links[0].clone())
}

#[test]
fn query_with_an_attached_object_is_free_under_a_dense_exact_recheck() {
    let s = setup();
    let g = build(&s, &params(7));
    let (tcp, touch) = right_hand(&s.world, &s.dec);
    let carried = attach_at_link(
        &s.world,
        "block",
        0,
        tcp,
        &Pose::translation(0.0, 0.0, 0.1),
        &s.base,
        touch,
    )
    .unwrap();
    assert_eq!(carried.attached.len(), 1);
    let space = g.space(&carried, s.base.clone()).unwrap();
    let mut solved = 0;
    for seed in 1..=3 {
        let goal = free_goal(&carried, &space, 100 + seed);
        let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(20));
        let r = query_super_graph(
            &g,
            &carried,
            &s.base,
            &goal,
            &RoadmapQuerySettings::default(),
            &mut term,
            seed,
        )
        .expect("query");
        assert_eq!(r.world_path.first().unwrap(), &s.base);
        assert_eq!(r.world_path.last().unwrap(), &goal);
        assert_certified_and_exactly_free(&carried, &r);
        solved += 1;
    }
    assert_eq!(solved, 3);
}

#[test]
fn lazy_revalidation_repairs_a_stretch_an_object_makes_invalid() {
    let s = setup();
    let g = build(&s, &params(9));
    let rw = roadmap_world(&s.world);
    let space = g.space(&rw, s.base.clone()).unwrap();
    // Every query below connects its start and goal to a fixed 40 nearest nodes per round (not
    // PRM*'s k for this graph), so the blocked query searches the path found here first.
    // A query the graph answers (not the straight motion).
    let mut found = None;
    for seed in 1..50 {
        let goal = free_goal(&rw, &space, 200 + seed);
        let r = query_super_graph(
            &g,
            &rw,
            &s.base,
            &goal,
            &RoadmapQuerySettings {
                shortcut: None,
                connect_nearest: Some(40),
                ..RoadmapQuerySettings::default()
            },
            &mut Termination::new(),
            seed,
        )
        .expect("query");
        if !r.stats.direct && r.stats.rrt_repairs == 0 && r.path.len() >= 4 {
            found = Some((goal, r));
            break;
        }
    }
    let (goal, r0) = found.expect("a graph query");
    // A box around the right palm at an inner node of that path.
    let mid = &r0.world_path[r0.path.len() / 2];
    let rob = &rw.robots[0];
    let mut poses = vec![Pose::identity(); rob.robot.links.len()];
    forward(&rob.robot, &rob.base, mid, &mut poses);
    let palm = rob.robot.link("right_palm").unwrap();
    let mut blocked = s.world.clone();
    blocked.statics.push(StaticBody {
        name: "blocker".into(),
        kind: StaticKind::Object,
        pose: Pose::from_parts(poses[palm].translation, Default::default()),
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Box {
                half_extents: [0.06, 0.06, 0.06].into(),
            },
        }],
    });
    assert!(!manyhands::collision::CollisionChecker::is_free(
        &mut FastChecker::new(&blocked),
        mid
    ));
    for max_searches in [20, 1] {
        let st = RoadmapQuerySettings {
            max_searches,
            connect_rounds: 1,
            connect_nearest: Some(40),
            ..RoadmapQuerySettings::default()
        };
        let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(20));
        let r =
            query_super_graph(&g, &blocked, &s.base, &goal, &st, &mut term, 1).expect("repaired");
        assert!(
            r.stats.invalid_nodes + r.stats.invalid_edges > 0,
            "{:?}",
            r.stats
        );
        if max_searches == 1 {
            // One search only: the invalid stretch is reconnected by RRT-Connect.
            assert!(r.stats.rrt_repairs > 0, "{:?}", r.stats);
        }
        assert_certified_and_exactly_free(&blocked, &r);
    }

    // The roadmap learns (003 §V-B, "enrich a graph computed using PRMs with RRTs"): the
    // repair's configurations and motions join the graph; the same query again is answered in
    // the enriched graph, with no repair.
    let one = RoadmapQuerySettings {
        max_searches: 1,
        connect_rounds: 1,
        connect_nearest: Some(40),
        ..RoadmapQuerySettings::default()
    };
    let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(20));
    let mut learned = LearnedGraph::default();
    let first = query_learning(
        &g,
        Some(&mut learned),
        &blocked,
        &s.base,
        &goal,
        &one,
        &mut term,
        1,
    )
    .expect("repaired");
    assert!(first.stats.rrt_repairs > 0, "{:?}", first.stats);
    assert!(first.stats.learned_added > 0, "{:?}", first.stats);
    assert_eq!(learned.nodes.len(), first.stats.learned_added);
    // Every learnt motion is certified in the world it was learnt in.
    let bspace = g.space(&blocked, s.base.clone()).unwrap();
    let mut v = manyhands::planning::SpaceValidator::new(
        bspace.clone(),
        &blocked,
        space_checker(&blocked, &bspace),
        0.02,
        0.01,
    )
    .with_certification(Some(FastChecker::CERTIFY_INFLATION));
    let n = g.nodes.len();
    let at = |i: u32| -> &Vec<f64> {
        if (i as usize) < n {
            &g.nodes[i as usize].q
        } else {
            &learned.nodes[i as usize - n]
        }
    };
    assert!(!learned.edges.is_empty());
    for &(a, b) in &learned.edges {
        assert!(v.is_motion_valid(at(a), at(b)), "learnt edge {a}-{b}");
    }
    let many = RoadmapQuerySettings {
        max_searches: 200,
        connect_rounds: 1,
        shortcut: None,
        connect_nearest: Some(40),
        ..RoadmapQuerySettings::default()
    };
    let again = query_learning(
        &g,
        Some(&mut learned),
        &blocked,
        &s.base,
        &goal,
        &many,
        &mut term,
        2,
    )
    .expect("answered in the enriched graph");
    assert_eq!(again.stats.rrt_repairs, 0, "{:?}", again.stats);
    // It goes through what was learnt (no shortcutting here to hide it).
    assert!(
        again.path.iter().any(|q| learned.nodes.contains(q)),
        "the answer does not use the learnt nodes: {:?}",
        again.stats
    );
    assert_eq!(again.stats.learned_nodes, first.stats.learned_added);
    assert_certified_and_exactly_free(&blocked, &again);
}

/// A query's start and goal try PRM*'s k nearest nodes per round when no number is set:
/// ⌈e (1 + 1/d) ln n⌉, growing with the roadmap, at least one, never more than the nodes.
#[test]
fn prm_star_k_is_karaman_and_frazzolis() {
    // The pick-and-place roadmap: 3 700 nodes of 17 variables.
    assert_eq!(prm_star_k(3700, 17), 24);
    assert_eq!(prm_star_k(100, 7), 15);
    assert_eq!(prm_star_k(1, 17), 1);
    assert_eq!(prm_star_k(3, 1), 3);
    let mut last = 0;
    for n in [10, 100, 1_000, 10_000, 100_000] {
        let k = prm_star_k(n, 6);
        assert!(k > last && k <= n, "n {n}: k {k}");
        last = k;
    }
}
