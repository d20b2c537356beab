//! The whole pick-and-place task of paper 003 (Fig. 2, §V-B): offline data, key
//! configurations, the four roadmap queries, and one trajectory with its grasp and release
//! events.
//!
//! **Offline** ([`prepare_pick_place`]): the single-grasp lists of both hands (003 §IV-A, from
//! the grasp-list cache, built when absent — "each one computed in about 1 minute" in 003 §VI,
//! an offline cost) and the super graph of torso + both arms (003 §V-A, from its roadmap file,
//! built when absent; [`crate::planning::planners::roadmap_cache`]).
//!
//! **Online** ([`plan_pick_place`]):
//! 1. the exchange grid (003 §V-C, Fig. 6) and the key configurations q_r^g, q_r^e, q_r^p of the
//!    best double grasp ([`super::key_configurations`]: single-grasp configurations, double
//!    grasps, exchange poses);
//! 2. the four queries of 003 §V-B — *grasp* (q_r^i → q_r^g, object resting at q_o^i),
//!    *carry* (q_r^g → q_r^e, object attached to the pick hand), *place* (q_r^e → q_r^p, attached
//!    to the place hand) and *rest* (q_r^p → q_r^i, object resting at q_o^f) — each answered in
//!    the super graph and lazily revalidated with the object, repaired by RRT-Connect where the
//!    object invalidates it ([`query_super_graph`]); or, with [`MotionPlanner::RrtConnect`],
//!    by plain RRT-Connect in the same space with the same certified checks (003 §VI's
//!    single-query comparison);
//! 3. the hands: the super graph moves torso and arms, so the fingers move in straight joint
//!    segments of their own, the arms still. A hand travels *pre-shaped* (free of the object:
//!    the hand may not touch what it does not hold) and closes on the object (grasp) or opens
//!    from it (release) along a certified closing motion of the grasp ([`super::fingers`]):
//!    only the grasp's contact fingertips touch the object, and only within the list's contact
//!    tolerance of their contacts, proven against the object's true geometry; the rest of the
//!    world with the object attached and the hand allowed to touch it.
//!
//! The plan's motions, in order: pick hand pre-shape at q_r^i; *grasp*; pick hand closes
//! (event: pick grasp); place hand pre-shape; *carry*; place hand closes (events: place grasp,
//! pick release); pick hand opens; *place* (event: place release); place hand opens; *rest*;
//! both hands back to their rest values.
//!
//! Bounded: the configuration search is bounded by its sample counts; the motion chain is tried
//! for at most [`PickPlaceSettings::attempts`] key-configuration searches (each with its own
//! seed, so another double grasp / exchange pose), within the task's [`Termination`]. A pose
//! out of reach ends at once in [`PickPlaceError::Unreachable`]. Every motion of the returned
//! plan is re-certified as a continuous motion ([`FastChecker::motion_certified`]) in the world
//! it was planned in (object resting or attached, fingers included) and every waypoint is within
//! the joint limits before the plan is returned. Deterministic per seed (unless the time limit
//! cuts a search).

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;
use thiserror::Error;

use super::approach::{
    approach_configuration, approach_directions, ApproachCertificate, ObjectCertificate,
    APPROACH_DISTANCES,
};
use super::configurations::{within_limits, ConfigParams, KeyConfigurations};
use super::fingers::FingerVerdict;
pub use super::hands::finger_preshape;
use super::hands::{closable, fingers_of, with_fingers};
use super::room::{first_free, SceneRoom, Test};
use super::{exchange_grid, key_configurations_with, ArmHand, PickPlaceError, PickPlaceProblem};
use crate::cache_tier::CacheTier;
use crate::collision::{
    BodyId, CollisionChecker, CollisionWorld, ExactChecker, FastChecker, StaticBody, StaticKind,
};
use crate::geometry::Pose;
use crate::grasp::{GraspList, GraspListCache, GraspListParams, GraspObject, SingleGrasp};
use crate::kinematics::link_pose;
use crate::planning::planners::roadmap_cache::{load_or_build, RoadmapSource};
use crate::planning::planners::roadmap_query::{
    attach_at_link, query_learning, LearnedGraph, RoadmapQuerySettings,
};
use crate::planning::planners::super_graph::{Decomposition, SuperGraph, SuperGraphParams};
use crate::planning::tasks::task::{EventKind, TaskEvent, TaskPhase, TaskPlan};
use crate::planning::{space_checker, PlanError, PlanStats, RrtConnect, Termination};

mod chain;

use chain::{certify, chain, Chain, CLOSING_CANDIDATES};

/// Why a pick-and-place task failed.
#[derive(Debug, Clone, Error)]
pub enum PickPlaceTaskError {
    /// The problem or its key configurations (request-caused: see [`PickPlaceError::field`]).
    #[error(transparent)]
    Problem(#[from] PickPlaceError),
    #[error("grasp list of '{hand}': {reason}")]
    GraspList { hand: String, reason: String },
    #[error("roadmap: {0}")]
    Roadmap(String),
    /// A query or a hand motion of one attempt.
    #[error("{phase}: {error}")]
    Phase { phase: String, error: PlanError },
    #[error("{0}")]
    Hand(String),
    #[error("no plan in {attempts} attempts; last failure: {last}")]
    Failed {
        attempts: usize,
        last: Box<PickPlaceTaskError>,
    },
    #[error("stopped ({0})")]
    Stopped(String),
    /// The final re-certification refused a motion (a bug if it happens).
    #[error("phase '{phase}' segment {segment}: {reason}")]
    NotCertified {
        phase: String,
        segment: usize,
        reason: String,
    },
}

impl PickPlaceTaskError {
    /// The request field a request-caused error is about (`None`: a planning failure).
    pub fn field(&self) -> Option<&str> {
        match self {
            PickPlaceTaskError::Problem(e) => match e {
                PickPlaceError::Unreachable { .. } | PickPlaceError::NoExchange(_) => None,
                e => Some(e.field()),
            },
            _ => None,
        }
    }

    /// True when the task ended by its time limit or stop flag.
    pub fn stopped(&self) -> bool {
        match self {
            PickPlaceTaskError::Stopped(_) => true,
            PickPlaceTaskError::Phase { error, .. } => matches!(
                error.root(),
                PlanError::Stopped { .. } | PlanError::Timeout { .. }
            ),
            PickPlaceTaskError::Failed { last, .. } => last.stopped(),
            _ => false,
        }
    }
}

/// How the four queries are answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionPlanner {
    /// The super graph with lazy revalidation and repair (003 §V-B).
    #[default]
    Roadmap,
    /// Plain RRT-Connect per query (003 §VI's single-query planner, the baseline).
    RrtConnect,
}

impl MotionPlanner {
    /// The planner named `name` (`roadmap`, `rrt_connect`; `-` may stand for `_`), the one
    /// parser of the CLI flag and the request field.
    pub fn from_name(name: &str) -> Option<MotionPlanner> {
        match name.replace('-', "_").as_str() {
            "roadmap" => Some(MotionPlanner::Roadmap),
            "rrt_connect" => Some(MotionPlanner::RrtConnect),
            _ => None,
        }
    }
}

/// What the super graph learns from its RRT repairs (003 §V-B,
/// [`crate::planning::planners::roadmap_query::LearnedGraph`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RoadmapLearning {
    /// Repairs serve the task's later queries and attempts (deterministic per seed).
    #[default]
    Task,
    /// Repairs are also kept in the offline data for later tasks on the same roadmap (a task
    /// then depends on the tasks before it).
    Shared,
}

/// Settings of the task.
#[derive(Debug, Clone)]
pub struct PickPlaceSettings {
    /// Parameters of both hands' grasp lists.
    pub lists: GraspListParams,
    /// The key-configuration search (its seed is set per attempt from the task's seed).
    pub config: ConfigParams,
    /// The super graph (its file is keyed by these).
    pub roadmap: SuperGraphParams,
    /// The queries (their RRT settings also serve [`MotionPlanner::RrtConnect`]).
    pub query: RoadmapQuerySettings,
    pub planner: MotionPlanner,
    /// Key-configuration searches (each a new seed) tried at most.
    pub attempts: usize,
    /// Pre-shape fractions tried, in order (module docs), each in (0, 1].
    pub finger_fractions: Vec<f64>,
    /// What the roadmap learns from its repairs.
    pub learning: RoadmapLearning,
}

impl Default for PickPlaceSettings {
    /// Default lists, search, roadmap (50 nodes per elementary roadmap as in 003 §VI) and
    /// queries; 4 attempts; pre-shapes at 100, 60, 30 and 15 % open.
    fn default() -> Self {
        PickPlaceSettings {
            lists: GraspListParams::default(),
            config: ConfigParams::default(),
            roadmap: SuperGraphParams::default(),
            query: RoadmapQuerySettings::default(),
            planner: MotionPlanner::Roadmap,
            attempts: 4,
            finger_fractions: vec![1.0, 0.6, 0.3, 0.15],
            learning: RoadmapLearning::Task,
        }
    }
}

impl PickPlaceSettings {
    pub fn validate(&self) -> Result<(), PickPlaceError> {
        self.config.validate()?;
        let bad = |f: &str, r: String| {
            Err(PickPlaceError::Invalid {
                field: f.into(),
                reason: r,
            })
        };
        if !(1..=100).contains(&self.attempts) {
            return bad(
                "attempts",
                format!("must be in 1..=100, got {}", self.attempts),
            );
        }
        if self.finger_fractions.is_empty()
            || self
                .finger_fractions
                .iter()
                .any(|s| !(s.is_finite() && *s > 0.0 && *s <= 1.0))
        {
            return bad(
                "finger_fractions",
                "give at least one fraction, each in (0, 1]".into(),
            );
        }
        Ok(())
    }
}

/// A progress report of the task (the server's SSE `progress`).
#[derive(Debug, Clone, Serialize)]
pub struct TaskProgress {
    /// `grasp_lists`, `roadmap`, `exchange`, `double_grasps`, `query_grasp`, `query_carry`,
    /// `query_place`, `query_rest`, `certification`.
    pub phase: &'static str,
    /// Attempt (0-based) of the online part.
    pub attempt: usize,
    pub elapsed_ms: f64,
}

/// Offline costs.
#[derive(Debug, Clone, Default, Serialize)]
pub struct OfflineStats {
    pub pick_list_ms: f64,
    pub place_list_ms: f64,
    /// The lists were built now (not found in the cache).
    pub pick_list_built: bool,
    pub place_list_built: bool,
    pub pick_grasps: usize,
    pub place_grasps: usize,
    pub roadmap_ms: f64,
    pub roadmap_built: bool,
    pub roadmap_file: Option<String>,
    pub roadmap_nodes: usize,
    pub roadmap_edges: usize,
    /// The roadmap's own build time (as recorded in it).
    pub roadmap_build_ms: f64,
}

/// The offline data of a task.
#[derive(Debug, Clone)]
pub struct PickPlaceOffline {
    pub pick_list: Arc<GraspList>,
    pub place_list: Arc<GraspList>,
    pub graph: Arc<SuperGraph>,
    /// The object as the grasp lists see it (the finger pre-shapes are checked against it).
    pub object: Arc<GraspObject>,
    /// Robot, obstacles and the object resting at q_o^i ([`task_world`]).
    pub world: CollisionWorld,
    pub stats: OfflineStats,
    /// What the super graph learnt from the repairs of earlier tasks
    /// ([`RoadmapLearning::Shared`]).
    pub learned: Arc<std::sync::Mutex<LearnedGraph>>,
    /// The grasps each hand can close on with a certified motion and those motions, computed
    /// by the first task (they depend on the hand, the object, the lists and the pre-shape
    /// fractions only, not on the scene), with the fractions they were computed for.
    pub closing: Arc<std::sync::Mutex<Option<ClosingCache>>>,
}

/// The closable grasps of both lists ([`PickPlaceOffline::closing`]): per hand the list of
/// closable grasps, their indices in the offline list and their certified closing motions.
#[derive(Debug, Clone)]
pub struct ClosingCache {
    pub fractions: Vec<f64>,
    pub hands: [super::fingers::Closable; 2],
}

/// Robot, obstacles and the object resting at its initial pose: the world of the task (its
/// roadmap is built in it, the object left out).
pub fn task_world(p: &PickPlaceProblem) -> CollisionWorld {
    let mut w = CollisionWorld::single(p.robot.clone(), p.base);
    w.statics = p.obstacles.clone();
    w.statics.push(StaticBody {
        name: p.object_name.clone(),
        kind: StaticKind::Object,
        pose: p.initial,
        shapes: p.object.clone(),
    });
    w
}

/// The decomposition of the robot for the super graph: the SRDF group whose variables are the
/// problem's torso (common part), the pick and place arms (independent parts).
pub fn decomposition(
    p: &PickPlaceProblem,
    world: &CollisionWorld,
) -> Result<Decomposition, PickPlaceTaskError> {
    let mut torso = p.torso.clone();
    torso.sort_unstable();
    let common = p
        .robot
        .groups
        .iter()
        .find(|g| {
            let mut v = g.vars.clone();
            v.sort_unstable();
            !v.is_empty() && v == torso
        })
        .map(|g| g.name.clone())
        .ok_or_else(|| {
            PickPlaceTaskError::Roadmap(format!(
                "robot '{}' has no SRDF group of exactly its torso variables",
                p.robot.name
            ))
        })?;
    Decomposition::from_groups(world, 0, &common, [&p.pick.arm_group, &p.place.arm_group])
        .map_err(|e| PickPlaceTaskError::Roadmap(e.to_string()))
}

/// The offline part (module docs): grasp lists from `lists` (built when absent; `stop` ends a
/// build) and the super graph from `roadmap_dir`, else from `roadmap_tier` (a shared
/// [`CacheTier`]), else built (saved there and published to the tier).
#[allow(clippy::too_many_arguments)]
pub fn prepare_pick_place(
    p: &PickPlaceProblem,
    settings: &PickPlaceSettings,
    lists: &GraspListCache,
    roadmap_dir: Option<&Path>,
    roadmap_tier: Option<&dyn CacheTier>,
    stop: &(dyn Fn() -> bool + Sync),
    term: &mut Termination,
    progress: &mut dyn FnMut(TaskProgress),
) -> Result<PickPlaceOffline, PickPlaceTaskError> {
    settings.validate()?;
    let t0 = Instant::now();
    let report = |phase, progress: &mut dyn FnMut(TaskProgress)| {
        progress(TaskProgress {
            phase,
            attempt: 0,
            elapsed_ms: t0.elapsed().as_secs_f64() * 1e3,
        })
    };
    let mut stats = OfflineStats::default();
    report("grasp_lists", progress);
    let object = GraspObject::new(&p.object_name, p.object.clone()).map_err(|e| {
        PickPlaceTaskError::Problem(PickPlaceError::Invalid {
            field: "object".into(),
            reason: e.to_string(),
        })
    })?;
    let list = |ah: &ArmHand| {
        let t = Instant::now();
        lists
            .get_or_build(&ah.hand, &object, &settings.lists, &|_, _| {}, stop)
            .map(|(l, built)| (l, built, t.elapsed().as_secs_f64() * 1e3))
            .map_err(|e| PickPlaceTaskError::GraspList {
                hand: ah.hand.group.clone(),
                reason: e.to_string(),
            })
    };
    let (pick_list, b0, ms0) = list(&p.pick)?;
    let (place_list, b1, ms1) = list(&p.place)?;
    stats.pick_list_ms = ms0;
    stats.place_list_ms = ms1;
    stats.pick_list_built = b0;
    stats.place_list_built = b1;
    stats.pick_grasps = pick_list.grasps.len();
    stats.place_grasps = place_list.grasps.len();
    report("roadmap", progress);
    let world = task_world(p);
    let dec = decomposition(p, &world)?;
    let t = Instant::now();
    let (graph, file, src) = load_or_build(
        roadmap_dir,
        roadmap_tier,
        &world,
        &dec,
        &p.rest,
        &settings.roadmap,
        term,
    )
    .map_err(|e| PickPlaceTaskError::Roadmap(e.to_string()))?;
    stats.roadmap_ms = t.elapsed().as_secs_f64() * 1e3;
    stats.roadmap_built = src == RoadmapSource::Built;
    stats.roadmap_file = file.map(|f| f.display().to_string());
    stats.roadmap_nodes = graph.nodes.len();
    stats.roadmap_edges = graph.edges.len();
    stats.roadmap_build_ms = graph.stats.total_millis;
    Ok(PickPlaceOffline {
        pick_list,
        place_list,
        graph: Arc::new(graph),
        object: Arc::new(object),
        world,
        stats,
        learned: Arc::default(),
        closing: Arc::default(),
    })
}

/// One of the four queries (003 Table I's columns).
#[derive(Debug, Clone, Default, Serialize)]
pub struct QueryRecord {
    /// `grasp`, `carry`, `place`, `rest`.
    pub name: String,
    pub planner: MotionPlanner,
    /// Online planning: super nodes on the first graph path (roadmap) or tree nodes (RRT).
    pub nodes: usize,
    pub planning_ms: f64,
    /// Path validation: nodes and edges revalidated with the object (roadmap only).
    pub validated: usize,
    pub invalid: usize,
    pub validation_ms: f64,
    pub rrt_repairs: usize,
    /// Learnt nodes searched beside the built graph, and nodes this query's repairs added.
    pub learned_nodes: usize,
    pub learned_added: usize,
    pub direct: bool,
    pub vertices: usize,
    pub total_ms: f64,
    /// Of the roadmap's planning time: start and goal connections, graph searches, RRT
    /// repairs, shortcutting (ms).
    pub connect_ms: f64,
    pub search_ms: f64,
    pub rrt_ms: f64,
    pub shortcut_ms: f64,
}

/// Online timings (ms).
#[derive(Debug, Clone, Default, Serialize)]
pub struct OnlineTimings {
    pub exchange_grid_ms: f64,
    /// The certified closing motions of both lists' grasps ([`super::fingers`]).
    pub closing_ms: f64,
    /// Single and double grasp configurations (all attempts).
    pub configurations_ms: f64,
    /// Queries and hand motions (all attempts).
    pub motions_ms: f64,
    pub certification_ms: f64,
    pub total_ms: f64,
}

/// The task's answer.
#[derive(Debug, Clone, Serialize)]
pub struct PickPlacePlan {
    /// World configurations (the task world: one robot), phases (the four queries and the hand
    /// motions, each with the world it was checked in) and events.
    pub plan: TaskPlan,
    pub keys: KeyConfigurations,
    /// The four queries of the successful attempt.
    pub queries: Vec<QueryRecord>,
    /// Attempts made (1 = the first key configurations were planned through).
    pub attempts: usize,
    /// Segments re-certified before the plan was returned.
    pub certified_segments: usize,
    /// Grasps of the pick and place lists the hand can close on with a certified motion
    /// ([`super::fingers`]).
    pub closable: [usize; 2],
    pub timings: OnlineTimings,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The online part of the task (module docs) with the offline data `off`.
pub fn plan_pick_place(
    p: &PickPlaceProblem,
    off: &PickPlaceOffline,
    settings: &PickPlaceSettings,
    seed: u64,
    term: &mut Termination,
    progress: &mut dyn FnMut(TaskProgress),
) -> Result<PickPlacePlan, PickPlaceTaskError> {
    settings.validate()?;
    let t0 = Instant::now();
    let mut timings = OnlineTimings::default();
    progress(TaskProgress {
        phase: "exchange",
        attempt: 0,
        elapsed_ms: 0.0,
    });
    let t = Instant::now();
    let grid = exchange_grid(p, &settings.config.exchange)?;
    timings.exchange_grid_ms = ms(t);
    // Only grasps the hand can close on with a certified motion (003 does not say how a hand
    // reaches its grasp; a grasp whose fingers cannot come to it free of the object is not
    // executable): `super::fingers`.
    let fr = &settings.finger_fractions;
    let t = Instant::now();
    let cached = off
        .closing
        .lock()
        .ok()
        .and_then(|c| c.as_ref().filter(|c| &c.fractions == fr).cloned());
    let cache = match cached {
        Some(c) => c,
        None => {
            let c = ClosingCache {
                fractions: fr.clone(),
                hands: [
                    closable(
                        &p.pick,
                        &off.object,
                        &off.pick_list,
                        &p.rest,
                        fr,
                        CLOSING_CANDIDATES,
                    ),
                    closable(
                        &p.place,
                        &off.object,
                        &off.place_list,
                        &p.rest,
                        fr,
                        CLOSING_CANDIDATES,
                    ),
                ],
            };
            if let Ok(mut slot) = off.closing.lock() {
                *slot = Some(c.clone());
            }
            c
        }
    };
    let [(mut pick_list, mut pick_index, mut pick_motions), (mut place_list, mut place_index, mut place_motions)] =
        cache.hands;
    timings.closing_ms = ms(t);
    for (ah, l, full) in [
        (&p.pick, &pick_list, &off.pick_list),
        (&p.place, &place_list, &off.place_list),
    ] {
        if l.grasps.is_empty() {
            return Err(PickPlaceTaskError::GraspList {
                hand: ah.hand.group.clone(),
                reason: format!(
                    "the hand can close on none of its {} grasps with a motion certified free \
                     of the object (some finger enters the object on every candidate motion)",
                    full.grasps.len()
                ),
            });
        }
    }
    let mut last: Option<PickPlaceTaskError> = None;
    let shared = settings.learning == RoadmapLearning::Shared;
    let mut learned = if shared {
        off.learned.lock().map(|l| l.clone()).unwrap_or_default()
    } else {
        LearnedGraph::default()
    };
    let keep = |learned: LearnedGraph| {
        if shared {
            if let Ok(mut l) = off.learned.lock() {
                if learned.nodes.len() > l.nodes.len() {
                    *l = learned;
                }
            }
        }
    };
    // A grasp none of whose closing motions is free in the scene is dropped and the search
    // runs again without it (not counted as an attempt; at most once per grasp).
    let mut attempt = 0;
    let mut dropped = 0;
    let droppable = pick_list.grasps.len() + place_list.grasps.len();
    while attempt < settings.attempts {
        if term.should_stop_now() {
            last = Some(PickPlaceTaskError::Stopped(format!(
                "time limit or stop request after {attempt} attempts"
            )));
            break;
        }
        let aseed = seed.wrapping_add(0x9E37_79B9u64.wrapping_mul(attempt as u64));
        progress(TaskProgress {
            phase: "double_grasps",
            attempt,
            elapsed_ms: ms(t0),
        });
        let t = Instant::now();
        let params = ConfigParams {
            seed: aseed,
            ..settings.config
        };
        // Only key configurations where the hands have room to close and open (`super::room`).
        let rooms = || {
            SceneRoom::new(
                p,
                &off.world,
                [&pick_list, &place_list],
                [&pick_motions, &place_motions],
            )
        };
        let (mut room, mut place_room) = (rooms(), rooms());
        let keys = key_configurations_with(
            p,
            &pick_list,
            &place_list,
            &grid,
            &params,
            [&mut room, &mut place_room],
        );
        drop((room, place_room));
        timings.configurations_ms += ms(t);
        let keys = match keys {
            Ok(k) => k,
            // Out of reach of a hand: no other seed helps in the same bounds.
            Err(e @ PickPlaceError::Unreachable { .. }) => return Err(e.into()),
            Err(e) => {
                last = Some(e.into());
                attempt += 1;
                continue;
            }
        };
        let t = Instant::now();
        let mut c = Chain {
            p,
            off,
            settings,
            pick_list: &pick_list,
            place_list: &place_list,
            pick_index: &pick_index,
            place_index: &place_index,
            pick_motions: &pick_motions,
            place_motions: &place_motions,
            plan: TaskPlan {
                waypoints: Vec::new(),
                phases: Vec::new(),
                events: Vec::new(),
                time: Duration::ZERO,
            },
            phase_world: Vec::new(),
            phase_fingers: Vec::new(),
            queries: Vec::new(),
            learned: std::mem::take(&mut learned),
            refused: None,
            seed: aseed,
            attempt,
            t0,
            worlds: Vec::new(),
            fast: Vec::new(),
            exact: Vec::new(),
        };
        let r = chain(&mut c, &keys, term, progress);
        learned = std::mem::take(&mut c.learned);
        let refused = c.refused;
        timings.motions_ms += ms(t);
        match r {
            Ok(()) => {
                progress(TaskProgress {
                    phase: "certification",
                    attempt,
                    elapsed_ms: ms(t0),
                });
                let t = Instant::now();
                let n = certify(
                    p,
                    &c.plan,
                    &c.worlds,
                    &c.phase_world,
                    &c.phase_fingers,
                    &mut c.fast,
                )?;
                timings.certification_ms = ms(t);
                timings.total_ms = ms(t0);
                keep(learned);
                let mut plan = c.plan;
                plan.time = t0.elapsed();
                // Indices into the offline lists, as the events name them.
                let mut keys = keys;
                keys.double.pick = pick_index[keys.double.pick];
                keys.double.place = place_index[keys.double.place];
                keys.grasp.grasp = pick_index[keys.grasp.grasp];
                keys.place.grasp = place_index[keys.place.grasp];
                return Ok(PickPlacePlan {
                    plan,
                    keys,
                    queries: c.queries,
                    attempts: attempt + 1,
                    certified_segments: n,
                    closable: [pick_index.len(), place_index.len()],
                    timings,
                });
            }
            Err(e) => {
                let stop = e.stopped();
                last = Some(e);
                if stop {
                    break;
                }
                match refused {
                    Some((side, g)) if dropped < droppable => {
                        let (list, index, motions) = if side == 0 {
                            (&mut pick_list, &mut pick_index, &mut pick_motions)
                        } else {
                            (&mut place_list, &mut place_index, &mut place_motions)
                        };
                        if list.grasps.len() > 1 && g < list.grasps.len() {
                            list.grasps.remove(g);
                            index.remove(g);
                            motions.remove(g);
                            dropped += 1;
                            continue;
                        }
                        attempt += 1;
                    }
                    _ => attempt += 1,
                }
            }
        }
    }
    keep(learned);
    Err(PickPlaceTaskError::Failed {
        attempts: settings.attempts,
        last: Box::new(last.unwrap_or_else(|| PickPlaceTaskError::Stopped("no attempt".into()))),
    })
}
