//! Online queries in a [`SuperGraph`] with lazy revalidation (paper 003 §V-B; Bohlin &
//! Kavraki's Lazy PRM, ref. \[22\]).
//!
//! 1. The start and the goal are connected to their nearest super nodes by certified straight
//!    motions in the query world (object included: resting in the scene, or attached to a hand
//!    while carried): every one of the [`RoadmapQuerySettings::connect_nearest`] nearest that
//!    such a motion reaches becomes a query edge.
//! 2. The shortest path (A*, the super space's weighted Euclidean distance) is searched in the
//!    graph *as built*, disregarding the object.
//! 3. Every node and edge of the path is then revalidated in the query world — a certified
//!    continuous motion check of every pair, so fingers closed on the object and the object
//!    itself are all covered; invalid ones are marked and the graph searched again, until a path
//!    is valid or none is left (or [`RoadmapQuerySettings::max_searches`] is reached). Then,
//!    up to [`RoadmapQuerySettings::connect_rounds`] times, the start and goal are connected to
//!    the next `connect_nearest` nodes and 2–3 run again, what was learnt kept: the key
//!    configurations of 003 §V-B lie near the object and the obstacles, where few straight
//!    motions to a compact roadmap are free, and the entries the object leaves valid are
//!    fewer still.
//! 4. Each stretch of the last path still invalid is reconnected by RRT-Connect in the query
//!    world ("if no solution is found, local reconnections are computed using RRT-like
//!    planners") between the collision-free configurations bounding it ("first, the
//!    collision-free configurations bounding the collision portion are determined"): not the
//!    graph nodes around it but the farthest configurations along its first and last edges that
//!    the valid nodes reach by certified motions.
//!    **The roadmap learns** ("it is easy to enrich a graph computed using PRMs with RRTs to
//!    efficiently reconnect the disconnected components"): with a [`LearnedGraph`], each repair's
//!    configurations become nodes and its motions edges, searched by later queries beside the
//!    built graph and, like the built graph, revalidated lazily in each query's world — so a
//!    learnt stretch is only ever used where it is valid, and nothing learnt needs to be
//!    invalidated when the object or its pose changes. The built graph itself is never changed
//!    (its file stays the offline one).
//! 5. The path is shortcut with the same certified validator (optional) and re-validated as a
//!    whole.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};
use std::time::Instant;

use rand::SeedableRng;
use serde::Serialize;

use crate::collision::{CollisionWorld, FastChecker};
use crate::planning::base::shortcut::{simplify, ShortcutSettings};
use crate::planning::base::validity::SegmentChecker;
use crate::planning::planners::super_graph::{SuperGraph, ANGULAR, LINEAR};
use crate::planning::{
    space_checker, JointSpace, PlanError, PlannerRng, RrtConnect, RrtConnectSettings,
    SpaceValidator, Termination,
};

/// Settings of [`query_super_graph`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RoadmapQuerySettings {
    /// Nearest super nodes tried for the start and goal connections (per round); `None`: PRM*'s
    /// number of neighbours for the graph searched ([`prm_star_k`]).
    pub connect_nearest: Option<usize>,
    /// Connection rounds at most: after a round whose searches found no valid path, the next
    /// `connect_nearest` nodes are tried (module docs, step 3); 1 = one round.
    pub connect_rounds: usize,
    /// Graph searches at most per connection round before the RRT reconnection.
    pub max_searches: usize,
    /// Settings of the RRT-Connect reconnection (its shortcutting included).
    pub rrt: RrtConnectSettings,
    /// Shortcut the final path (`None`: as found).
    pub shortcut: Option<ShortcutSettings>,
}

impl Default for RoadmapQuerySettings {
    fn default() -> Self {
        // PRM*'s k nearest per round (24 on the pick-and-place task's 3 700-node graph of 17
        // variables), two rounds. `bench pick-place`, 20 seeded runs, one core: the queries'
        // median 35 → 26 ms against a fixed 40 per round (the place query tried 80 straight
        // connections before its first search, most of them long and invalid with the object);
        // 12 per round made the carry query repair in 8 of 20 runs.
        RoadmapQuerySettings {
            connect_nearest: None,
            connect_rounds: 2,
            max_searches: 20,
            rrt: RrtConnectSettings {
                certify: Some(FastChecker::CERTIFY_INFLATION),
                ..RrtConnectSettings::default()
            },
            shortcut: Some(ShortcutSettings::default()),
        }
    }
}

/// PRM*'s number of neighbours, k = ⌈e (1 + 1/d) ln n⌉ (Karaman & Frazzoli, "Sampling-based
/// algorithms for optimal motion planning", IJRR 2011, §3.3), for a roadmap of `n` nodes in a
/// `d`-dimensional space: how many nearest nodes a query's start and goal try per round when
/// [`RoadmapQuerySettings::connect_nearest`] is unset. At least 1.
pub fn prm_star_k(n: usize, d: usize) -> usize {
    if n < 2 || d == 0 {
        return n.max(1);
    }
    let k = std::f64::consts::E * (1.0 + 1.0 / d as f64) * (n as f64).ln();
    (k.ceil() as usize).clamp(1, n)
}

/// What a query did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RoadmapQueryStats {
    /// The straight start–goal motion was free: no graph needed.
    pub direct: bool,
    pub start_connections: usize,
    pub goal_connections: usize,
    /// Graph searches (A*) run.
    pub searches: usize,
    /// Connection rounds run (module docs, step 3).
    pub connect_rounds: usize,
    /// Super nodes on the first path found.
    pub first_path_nodes: usize,
    /// Nodes and edges revalidated with the object, and how many were invalid.
    pub nodes_validated: usize,
    pub edges_validated: usize,
    pub invalid_nodes: usize,
    pub invalid_edges: usize,
    /// Stretches reconnected by RRT-Connect.
    pub rrt_repairs: usize,
    /// Learnt nodes searched, and nodes added by this query's repairs ([`LearnedGraph`]).
    pub learned_nodes: usize,
    pub learned_added: usize,
    pub vertices: usize,
    pub length: f64,
    pub connect_ms: f64,
    pub search_ms: f64,
    pub validation_ms: f64,
    pub rrt_ms: f64,
    pub shortcut_ms: f64,
    pub total_ms: f64,
}

/// A query's answer: states of the super space, and the same as world configurations.
#[derive(Debug, Clone)]
pub struct RoadmapPath {
    pub space: JointSpace,
    pub path: Vec<Vec<f64>>,
    pub world_path: Vec<Vec<f64>>,
    pub stats: RoadmapQueryStats,
}

#[derive(Clone, Copy, PartialEq)]
struct Open {
    f: f64,
    node: u32,
}
impl Eq for Open {}
impl Ord for Open {
    fn cmp(&self, o: &Self) -> Ordering {
        o.f.total_cmp(&self.f).then(o.node.cmp(&self.node))
    }
}
impl PartialOrd for Open {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// Nodes and edges learnt from RRT repairs (module docs, step 4): super-space configurations
/// and undirected edges between ids, an id below the super graph's node count naming a built
/// node and `n + i` the learnt node `i` (`n` the super graph's node count, fixed for one
/// graph). Every learnt motion was certified in the world of the query that learnt it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LearnedGraph {
    pub nodes: Vec<Vec<f64>>,
    pub edges: Vec<(u32, u32)>,
}

impl LearnedGraph {
    /// Most learnt nodes kept (later repairs are still answered, not learnt).
    pub const MAX_NODES: usize = 20_000;

    fn add_path(&mut self, n: usize, ends: (Option<u32>, Option<u32>), path: &[Vec<f64>]) {
        if path.len() < 2 || self.nodes.len() + path.len() > Self::MAX_NODES {
            return;
        }
        let mut ids = Vec::with_capacity(path.len());
        for (k, q) in path.iter().enumerate() {
            let known = match k {
                0 => ends.0,
                _ if k + 1 == path.len() => ends.1,
                _ => None,
            };
            ids.push(known.unwrap_or_else(|| {
                self.nodes.push(q.clone());
                (n + self.nodes.len() - 1) as u32
            }));
        }
        for w in ids.windows(2) {
            let e = (w[0].min(w[1]), w[0].max(w[1]));
            if e.0 != e.1 && !self.edges.contains(&e) {
                self.edges.push(e);
            }
        }
    }
}

/// A repaired stretch: the graph ids of its ends (`None`: the query's start or goal) and its
/// configurations.
type LearntStretch = ((Option<u32>, Option<u32>), Vec<Vec<f64>>);

/// Lazy validity of a node or edge: unknown, valid or invalid in the query world.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Known {
    Unknown,
    Valid,
    Invalid,
}

/// Plans from world configuration `start` to `goal` (equal outside the super graph's
/// variables) in `world` — the super graph's robots with the object resting or attached (module
/// docs). Every returned segment is a certified continuous motion in `world`.
pub fn query_super_graph(
    sg: &SuperGraph,
    world: &CollisionWorld,
    start: &[f64],
    goal: &[f64],
    settings: &RoadmapQuerySettings,
    term: &mut Termination,
    seed: u64,
) -> Result<RoadmapPath, PlanError> {
    query_learning(sg, None, world, start, goal, settings, term, seed)
}

/// [`query_super_graph`] searching the learnt nodes and edges of `learned` beside the super
/// graph's and adding this query's repairs to it (module docs, step 4).
#[allow(clippy::too_many_arguments)]
pub fn query_learning(
    sg: &SuperGraph,
    learned: Option<&mut LearnedGraph>,
    world: &CollisionWorld,
    start: &[f64],
    goal: &[f64],
    settings: &RoadmapQuerySettings,
    term: &mut Termination,
    seed: u64,
) -> Result<RoadmapPath, PlanError> {
    let t0 = Instant::now();
    let mut st = RoadmapQueryStats::default();
    if world.dof() != sg.base.len() {
        return Err(PlanError::InvalidInput(format!(
            "the world has {} variables, the roadmap's {}",
            world.dof(),
            sg.base.len()
        )));
    }
    if start.len() != world.dof() || goal.len() != world.dof() {
        return Err(PlanError::InvalidInput(format!(
            "start and goal need {} values",
            world.dof()
        )));
    }
    let vars = sg.decomposition.super_vars();
    if let Some(i) = (0..start.len()).find(|i| !vars.contains(i) && start[*i] != goal[*i]) {
        return Err(PlanError::InvalidInput(format!(
            "start and goal differ in variable {i}, outside the roadmap's variables"
        )));
    }
    let space = sg.space(world, start.to_vec())?;
    let checker = space_checker(world, &space);
    let mut v = SpaceValidator::new(space.clone(), world, checker, ANGULAR, LINEAR)
        .with_certification(
            settings
                .rrt
                .certify
                .or(Some(FastChecker::CERTIFY_INFLATION)),
        );
    let s = space.from_world(start);
    let g = space.from_world(goal);
    if let Some(reason) = v.invalidity(&s) {
        return Err(PlanError::InvalidStart { reason });
    }
    if let Some(reason) = v.invalidity(&g) {
        return Err(PlanError::InvalidGoal { count: 1, reason });
    }
    let mut rng = PlannerRng::seed_from_u64(seed);

    // 1. Connections (or the straight motion itself).
    let tc = Instant::now();
    let built = sg.nodes.len();
    let none = LearnedGraph::default();
    // A copy: the repairs below add to `learned` while the search reads this.
    let known: LearnedGraph = learned.as_deref().cloned().unwrap_or_default();
    // Learnt nodes whose dimension does not fit (another graph's) are not used.
    let usable = if known.nodes.iter().all(|q| q.len() == space.dim()) {
        &known
    } else {
        &none
    };
    st.learned_nodes = usable.nodes.len();
    let n = (built + usable.nodes.len()) as u32;
    let (vs, vg) = (n, n + 1);
    let mut extra: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut path: Vec<Vec<f64>>;
    if v.is_motion_valid(&s, &g) {
        st.direct = true;
        path = vec![s.clone(), g.clone()];
        st.connect_ms = tc.elapsed().as_secs_f64() * 1e3;
    } else {
        // Super nodes by distance to the start and to the goal.
        let by_distance = |q: &[f64]| -> Vec<u32> {
            let mut near: Vec<(f64, u32)> = sg
                .nodes
                .iter()
                .map(|nd| &nd.q)
                .chain(&usable.nodes)
                .enumerate()
                .map(|(i, x)| (space.distance_sq(q, x), i as u32))
                .collect();
            near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            near.into_iter().map(|(_, i)| i).collect()
        };
        let near = [by_distance(&s), by_distance(&g)];
        st.connect_ms = tc.elapsed().as_secs_f64() * 1e3;
        let state = |i: u32| -> &Vec<f64> {
            if i == vs {
                &s
            } else if i == vg {
                &g
            } else if (i as usize) < built {
                &sg.nodes[i as usize].q
            } else {
                &usable.nodes[i as usize - built]
            }
        };

        // 2–3. Search, revalidate lazily, search again; connect further nodes and go on.
        let mut neighbours = sg.neighbours();
        neighbours.resize(n as usize, Vec::new());
        for &(a, b) in &usable.edges {
            if a < n && b < n {
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
        let mut node_ok = vec![Known::Unknown; n as usize + 2];
        node_ok[vs as usize] = Known::Valid;
        node_ok[vg as usize] = Known::Valid;
        let mut edge_ok: HashMap<(u32, u32), Known> = HashMap::new();
        let mut last: Option<Vec<u32>> = None;
        let mut graph_path: Option<Vec<u32>> = None;
        let batch = settings
            .connect_nearest
            .unwrap_or_else(|| prm_star_k(n as usize, space.dim()))
            .max(1);
        for round in 0..settings.connect_rounds.max(1) {
            let tried = round * batch;
            if tried >= n as usize || term.should_stop_now() {
                break;
            }
            st.connect_rounds += 1;
            let tc = Instant::now();
            for (virt, q, near) in [(vs, &s, &near[0]), (vg, &g, &near[1])] {
                for &i in near.iter().skip(tried).take(batch) {
                    if v.is_motion_valid(q, state(i)) {
                        extra.entry(virt).or_default().push(i);
                        extra.entry(i).or_default().push(virt);
                        edge_ok.insert((i.min(virt), i.max(virt)), Known::Valid);
                    }
                }
            }
            st.start_connections = extra.get(&vs).map_or(0, |e| e.len());
            st.goal_connections = extra.get(&vg).map_or(0, |e| e.len());
            st.connect_ms += tc.elapsed().as_secs_f64() * 1e3;
            if st.start_connections == 0 || st.goal_connections == 0 {
                continue; // no search can join them yet
            }
            let mut searches = 0;
            while searches < settings.max_searches.max(1) {
                if term.should_stop_now() {
                    break;
                }
                let ts = Instant::now();
                searches += 1;
                st.searches += 1;
                let found = astar(
                    n as usize + 2,
                    vs,
                    vg,
                    |a, out: &mut Vec<u32>| {
                        out.clear();
                        if (a as usize) < neighbours.len() {
                            out.extend(&neighbours[a as usize]);
                        }
                        if let Some(e) = extra.get(&a) {
                            out.extend(e);
                        }
                        out.retain(|&b| {
                            node_ok[b as usize] != Known::Invalid
                                && edge_ok.get(&(a.min(b), a.max(b))) != Some(&Known::Invalid)
                        });
                    },
                    |a, b| space.distance(state(a), state(b)),
                );
                st.search_ms += ts.elapsed().as_secs_f64() * 1e3;
                let Some(p) = found else { break };
                if st.first_path_nodes == 0 {
                    st.first_path_nodes = p.len().saturating_sub(2);
                }
                let tv = Instant::now();
                let all_ok = revalidate(&mut v, &p, state, (&mut node_ok, &mut edge_ok), &mut st);
                st.validation_ms += tv.elapsed().as_secs_f64() * 1e3;
                if all_ok {
                    graph_path = Some(p);
                    break;
                }
                last = Some(p);
            }
            if graph_path.is_some() {
                break;
            }
        }
        path = Vec::new();
        match graph_path {
            Some(p) => path.extend(p.iter().map(|&i| state(i).clone())),
            None => {
                // 4. RRT-Connect over each invalid stretch of the last path (or the whole
                // query when the graph never joined start and goal).
                let p = last.unwrap_or_else(|| vec![vs, vg]);
                let mut rrt = RrtConnect::with_checker(
                    space.clone(),
                    world,
                    space_checker(world, &space),
                    settings.rrt,
                )?;
                let tr = Instant::now();
                path.push(s.clone());
                let mut learnt: Vec<LearntStretch> = Vec::new();
                let graph_id = |i: u32| (i < n).then_some(i);
                let mut i = 0;
                while i + 1 < p.len() {
                    let (a, b) = (p[i], p[i + 1]);
                    if node_ok[b as usize] == Known::Valid
                        && edge_ok.get(&(a.min(b), a.max(b))) == Some(&Known::Valid)
                    {
                        path.push(state(p[i + 1]).clone());
                        i += 1;
                        continue;
                    }
                    let j = (i + 1..p.len())
                        .find(|&j| node_ok[p[j] as usize] == Known::Valid)
                        .unwrap_or(p.len() - 1);
                    // The free configurations bounding the invalid stretch: as far along its
                    // first edge from p[i], and along its last edge from p[j], as certified
                    // motions reach.
                    let from = reach_along(&mut v, state(p[i]), state(p[i + 1]));
                    let to = reach_along(&mut v, state(p[j]), state(p[j - 1]));
                    st.rrt_repairs += 1;
                    let r = rrt.plan(
                        &from,
                        std::slice::from_ref(&to),
                        term,
                        seed.wrapping_add(st.rrt_repairs as u64),
                    )?;
                    let mut stretch = Vec::with_capacity(r.path.len() + 2);
                    stretch.push(state(p[i]).clone());
                    if &from != state(p[i]) {
                        stretch.push(from);
                    }
                    stretch.extend(r.path.into_iter().skip(1));
                    if stretch.last() != Some(&to) {
                        stretch.push(to.clone());
                    }
                    if &to != state(p[j]) {
                        stretch.push(state(p[j]).clone());
                    }
                    path.extend(stretch.iter().skip(1).cloned());
                    learnt.push(((graph_id(p[i]), graph_id(p[j])), stretch));
                    i = j;
                }
                if let Some(l) = learned {
                    // Ids of the usable graph only (a mismatched store starts over).
                    if l.nodes.len() != usable.nodes.len() {
                        *l = LearnedGraph::default();
                    }
                    let before = l.nodes.len();
                    for (ends, stretch) in &learnt {
                        l.add_path(built, *ends, stretch);
                    }
                    st.learned_added = l.nodes.len() - before;
                }
                st.rrt_ms = tr.elapsed().as_secs_f64() * 1e3;
            }
        }
    }

    // 5. Shortcut and re-validate.
    if let Some(sc) = &settings.shortcut {
        let tsc = Instant::now();
        simplify(&mut v, &mut path, sc, &mut rng, term);
        st.shortcut_ms = tsc.elapsed().as_secs_f64() * 1e3;
    }
    if let Err(k) = v.validate_path(&path) {
        return Err(PlanError::PathInvalid {
            segment: k,
            stats: Box::default(),
        });
    }
    st.vertices = path.len();
    st.length = space.path_length(&path);
    st.total_ms = t0.elapsed().as_secs_f64() * 1e3;
    let world_path = space.path_to_world(&path);
    Ok(RoadmapPath {
        space,
        path,
        world_path,
        stats: st,
    })
}

/// The farthest configuration along the straight motion `a → b` that a certified motion from
/// `a` reaches, of the fractions 1, 3/4, 1/2, 1/4, 1/8 (`a` itself when none).
fn reach_along<C: SegmentChecker>(v: &mut SpaceValidator<C>, a: &[f64], b: &[f64]) -> Vec<f64> {
    for f in [1.0, 0.75, 0.5, 0.25, 0.125] {
        let q: Vec<f64> = a.iter().zip(b).map(|(x, y)| x + f * (y - x)).collect();
        if v.is_state_valid(&q) && v.is_motion_valid(a, &q) {
            return q;
        }
    }
    a.to_vec()
}

/// Step 3, lazy revalidation: the nodes, then the edges between valid nodes, of graph path `p`
/// not checked yet are checked in the query world (`state` gives a node's configuration) and
/// marked valid or invalid. True when every node and edge of `p` is valid.
fn revalidate<'a, C: SegmentChecker>(
    v: &mut SpaceValidator<C>,
    p: &[u32],
    state: impl Fn(u32) -> &'a Vec<f64>,
    (node_ok, edge_ok): (&mut [Known], &mut HashMap<(u32, u32), Known>),
    st: &mut RoadmapQueryStats,
) -> bool {
    let mut all_ok = true;
    for &a in p {
        if node_ok[a as usize] == Known::Unknown {
            st.nodes_validated += 1;
            node_ok[a as usize] = if v.is_state_valid(state(a)) {
                Known::Valid
            } else {
                st.invalid_nodes += 1;
                Known::Invalid
            };
        }
        all_ok &= node_ok[a as usize] == Known::Valid;
    }
    for w in p.windows(2) {
        if node_ok[w[0] as usize] != Known::Valid || node_ok[w[1] as usize] != Known::Valid {
            continue;
        }
        let e = edge_ok
            .entry((w[0].min(w[1]), w[0].max(w[1])))
            .or_insert(Known::Unknown);
        if *e == Known::Unknown {
            st.edges_validated += 1;
            *e = if v.is_motion_valid(state(w[0]), state(w[1])) {
                Known::Valid
            } else {
                st.invalid_edges += 1;
                Known::Invalid
            };
        }
        all_ok &= *e == Known::Valid;
    }
    all_ok
}

/// A* from `from` to `to` over nodes `0..n` (`succ` fills the usable neighbours, `cost` is the
/// edge length and, being a metric, the admissible heuristic). The node sequence, or `None`.
fn astar(
    n: usize,
    from: u32,
    to: u32,
    mut succ: impl FnMut(u32, &mut Vec<u32>),
    cost: impl Fn(u32, u32) -> f64,
) -> Option<Vec<u32>> {
    let mut g = vec![f64::INFINITY; n];
    let mut parent = vec![u32::MAX; n];
    let mut closed = vec![false; n];
    let mut open = BinaryHeap::new();
    g[from as usize] = 0.0;
    open.push(Open {
        f: cost(from, to),
        node: from,
    });
    let mut buf = Vec::new();
    while let Some(Open { node, .. }) = open.pop() {
        if closed[node as usize] {
            continue;
        }
        if node == to {
            let mut p = vec![to];
            let mut c = to;
            while c != from {
                c = parent[c as usize];
                p.push(c);
            }
            p.reverse();
            return Some(p);
        }
        closed[node as usize] = true;
        succ(node, &mut buf);
        for &b in &buf {
            if closed[b as usize] {
                continue;
            }
            let ng = g[node as usize] + cost(node, b);
            if ng < g[b as usize] {
                g[b as usize] = ng;
                parent[b as usize] = node;
                open.push(Open {
                    f: ng + cost(b, to),
                    node: b,
                });
            }
        }
    }
    None
}

/// `world` with its free object `object` held by link `link` of robot `robot`: the object's
/// frame at `grasp` in the link frame at world configuration `q`, the links `touch` allowed to
/// touch it (what a carry query of 003 §V-B revalidates against: "the CS also changes when the
/// robot carries the object").
pub fn attach_at_link(
    world: &CollisionWorld,
    object: &str,
    robot: usize,
    link: usize,
    grasp: &crate::geometry::Pose,
    q: &[f64],
    touch: Vec<usize>,
) -> Result<CollisionWorld, PlanError> {
    let mut w = world.clone();
    let p = w
        .robots
        .get(robot)
        .ok_or_else(|| PlanError::InvalidInput(format!("robot {robot} is not in the world")))?;
    if link >= p.robot.links.len() || q.len() != w.dof() {
        return Err(PlanError::InvalidInput(format!(
            "link {link} or a configuration of {} values does not fit robot '{}'",
            q.len(),
            p.name
        )));
    }
    let mut poses = vec![crate::geometry::Pose::identity(); p.robot.links.len()];
    crate::kinematics::forward(&p.robot, &p.base, w.robot_config(robot, q), &mut poses);
    let si = w
        .statics
        .iter()
        .position(|s| s.name == object)
        .ok_or_else(|| PlanError::InvalidInput(format!("no free object '{object}'")))?;
    w.statics[si].pose = poses[link] * grasp;
    w.attach(object, robot, link, q, touch)
        .ok_or_else(|| PlanError::InvalidInput(format!("cannot attach '{object}'")))?;
    Ok(w)
}
