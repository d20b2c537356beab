//! The super graph of paper 003 §V-A (Gharbi, Cortés & Siméon, "Roadmap composition for
//! multi-arm systems path planning", IROS 2009, ref. \[4\]): a humanoid decomposed into
//! kinematically *independent* parts (the arms) and a *common* one (the torso), one compact
//! elementary roadmap per sub-system "common + independent part" ([`visibility_prm`]), composed
//! into one roadmap of the whole system.
//!
//! **Elementary roadmaps.** Roadmap `k` lives in the space of the common variables and part
//! `k`'s (torso + one arm). It is checked in the roadmap world — the scene's obstacles; its free
//! objects are left out, the object to move is revalidated online (§V-B) — with every pair that
//! involves a link of the *other* part not checked: the other arm and its hand are ignored, as
//! in 003 ("such roadmaps construction considers self-collisions of the sub-system and collisions
//! with the obstacles"). Every variable outside the space (the other arm, the fingers) keeps its
//! value in the base configuration. So a node or edge of roadmap `k` is certified free for the
//! pairs (common ∪ part `k` ∪ other robots' links) × (the same ∪ obstacles).
//!
//! **Nodes** (§V-A.1). Elementary nodes `x₀ ∈ R₀`, `x₁ ∈ R₁` disagree on the torso, so their
//! merge gives two super nodes, `(t(x₀), a₀(x₀), a₁(x₁))` and `(t(x₁), a₀(x₀), a₁(x₁))`
//! ("merging consists of creating two SG nodes, obtained by fusing configurations of the
//! independent parts"). In the node taking its torso from `x_c` part `c`'s links are in the very
//! configuration checked in `R_c`; only the pairs of the other part `c̄` against everything but
//! itself (its internal pairs depend on its own joints only, checked in `R_c̄`) are checked.
//!
//! **Edges** (§V-A.2). Two super nodes `X`, `Y` are tried only when their elementary nodes are
//! linked in both roadmaps — joined by an elementary edge, or (with
//! [`SuperGraphParams::stationary`]) the same node: that part stands still. When both take
//! their torso from the same part `c`, part `c` moves along its elementary edge (or not at all),
//! certified in `R_c`, and only the pairs of part `c̄` against the rest are checked; when they take
//! it from different parts, every pair but the parts' internal ones is. Every check is a
//! certified continuous motion check of the planners' [`FastChecker`]. With
//! [`SuperGraphParams::tree`] only edges joining two components are tried (003's "roadmap tree").
//!
//! The graph is built offline and kept in a file keyed by the robot, the roadmap world and the
//! parameters ([`crate::planning::planners::roadmap_cache`]). Queries and the online lazy revalidation with the
//! object are in [`crate::planning::planners::roadmap_query`].

use std::collections::HashSet;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::collision::{BodyId, CollisionWorld, FastChecker, StaticKind};
use crate::planning::planners::visibility_prm::{
    visibility_prm, Roadmap, UnionFind, VisibilityPrmSettings,
};
use crate::planning::{space_checker, JointSpace, PlanError, SpaceValidator, Termination};

/// Resolutions of the (uncertified) fallback state checks: 0.5°, 5 mm.
pub(crate) const ANGULAR: f64 = 0.008_726_646_259_971_648;
pub(crate) const LINEAR: f64 = 0.005;

/// The decomposition of one robot of a world into a common part and two independent parts,
/// from SRDF groups (003 Fig. 4: the torso is common, the arms are independent; the head, fixed
/// here, rides with the torso).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decomposition {
    /// Index of the robot in the world.
    pub robot: usize,
    pub common_group: String,
    pub part_groups: [String; 2],
    /// World variables of the common part.
    pub common: Vec<usize>,
    /// World variables of each independent part.
    pub parts: [Vec<usize>; 2],
    /// Links (of the robot) each independent part moves: every link below one of its joints.
    pub part_links: [Vec<usize>; 2],
}

impl Decomposition {
    /// The decomposition of robot `robot` of `world` into the group `common` and the groups
    /// `parts` (e.g. `torso`, `[right_arm, left_arm]`). Refused when a group is missing or
    /// empty, when groups share a variable, when a part moves a link of the other or of the
    /// common part (the parts would not be independent), or when the common part is empty.
    pub fn from_groups(
        world: &CollisionWorld,
        robot: usize,
        common: &str,
        parts: [&str; 2],
    ) -> Result<Decomposition, PlanError> {
        let p = world
            .robots
            .get(robot)
            .ok_or_else(|| PlanError::InvalidInput(format!("robot {robot} is not in the world")))?;
        let r = &p.robot;
        let vars_of = |g: &str| -> Result<Vec<usize>, PlanError> {
            let grp = r.group(g).ok_or_else(|| {
                PlanError::InvalidInput(format!("robot '{}' has no group '{g}'", p.name))
            })?;
            if grp.vars.is_empty() {
                return Err(PlanError::InvalidInput(format!(
                    "group '{g}' of '{}' has no variables",
                    p.name
                )));
            }
            Ok(grp.vars.clone())
        };
        let c = vars_of(common)?;
        let a = vars_of(parts[0])?;
        let b = vars_of(parts[1])?;
        for (x, y, nx, ny) in [
            (&c, &a, common, parts[0]),
            (&c, &b, common, parts[1]),
            (&a, &b, parts[0], parts[1]),
        ] {
            if let Some(v) = x.iter().find(|v| y.contains(v)) {
                return Err(PlanError::InvalidInput(format!(
                    "groups '{nx}' and '{ny}' share the variable {}",
                    r.var_name(*v)
                )));
            }
        }
        let moved = |vars: &[usize]| -> Vec<usize> {
            (0..r.links.len())
                .filter(|&l| {
                    let mut link = l;
                    while let Some(j) = r.links[link].parent_joint {
                        let jt = &r.joints[j];
                        let var = jt.var.or(jt.mimic.as_ref().map(|m| m.var));
                        if var.is_some_and(|v| vars.contains(&v)) {
                            return true;
                        }
                        link = jt.parent;
                    }
                    false
                })
                .collect()
        };
        let la = moved(&a);
        let lb = moved(&b);
        if let Some(l) = la.iter().find(|l| lb.contains(l)) {
            return Err(PlanError::InvalidInput(format!(
                "'{}' and '{}' both move link {}: not independent parts",
                parts[0], parts[1], r.links[*l].name
            )));
        }
        // A common joint below a part would make the part move the common part.
        for &v in &c {
            let child = r.joints[r.vars[v]].child;
            if la.contains(&child) || lb.contains(&child) {
                return Err(PlanError::InvalidInput(format!(
                    "common variable {} lies below an independent part",
                    r.var_name(v)
                )));
            }
        }
        let world_vars = |v: &[usize]| v.iter().map(|x| x + p.offset).collect::<Vec<_>>();
        Ok(Decomposition {
            robot,
            common_group: common.to_string(),
            part_groups: [parts[0].to_string(), parts[1].to_string()],
            common: world_vars(&c),
            parts: [world_vars(&a), world_vars(&b)],
            part_links: [la, lb],
        })
    }

    /// World variables of elementary roadmap `k`: common, then part `k`.
    pub fn elementary_vars(&self, k: usize) -> Vec<usize> {
        let mut v = self.common.clone();
        v.extend(&self.parts[k]);
        v
    }

    /// World variables of the super graph: common, part 0, part 1.
    pub fn super_vars(&self) -> Vec<usize> {
        let mut v = self.common.clone();
        v.extend(&self.parts[0]);
        v.extend(&self.parts[1]);
        v
    }

    /// The part (0, 1) a body belongs to, `None` for the common part, other robots and fixed
    /// or attached bodies.
    pub fn part_of(&self, id: BodyId) -> Option<usize> {
        match id {
            BodyId::Link { robot, link } if robot == self.robot => {
                (0..2).find(|&k| self.part_links[k].contains(&link))
            }
            _ => None,
        }
    }

    /// `world` with every checked pair for which `keep` is false made an allowed pair.
    pub fn restricted(
        &self,
        world: &CollisionWorld,
        keep: impl Fn(Option<usize>, Option<usize>) -> bool,
    ) -> CollisionWorld {
        let mut w = world.clone();
        for (a, b) in world.pairs() {
            if !keep(self.part_of(a), self.part_of(b)) {
                w.allow(a, b);
            }
        }
        w
    }

    /// The world of elementary roadmap `k`: pairs with a link of the other part not checked.
    pub fn elementary_world(&self, world: &CollisionWorld, k: usize) -> CollisionWorld {
        let other = Some(1 - k);
        self.restricted(world, |a, b| a != other && b != other)
    }

    /// The pairs not checked in the roadmap of the part other than `p`: those of part `p`
    /// against every body outside it.
    pub fn part_world(&self, world: &CollisionWorld, p: usize) -> CollisionWorld {
        let p = Some(p);
        self.restricted(world, |a, b| (a == p) != (b == p))
    }

    /// Every pair except those inside one independent part.
    pub fn mixed_world(&self, world: &CollisionWorld) -> CollisionWorld {
        self.restricted(world, |a, b| a.is_none() || a != b)
    }
}

/// The roadmap world of a scene world: its obstacles only (free objects left out, 003 §V-A:
/// "only self-collisions and collisions against static objects are considered while ignoring
/// the object to move"), nothing attached.
pub fn roadmap_world(world: &CollisionWorld) -> CollisionWorld {
    let mut w = world.clone();
    w.attached.clear();
    w.allowed.clear();
    w.statics.retain(|s| s.kind == StaticKind::Obstacle);
    w
}

/// Parameters of [`build_super_graph`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SuperGraphParams {
    /// Visibility-PRM of each elementary roadmap (roadmap `k` is seeded with `seed + k`).
    pub prm: VisibilityPrmSettings,
    /// A part may stand still on a super edge (its elementary node linked to itself).
    pub stationary: bool,
    /// Only try edges between super nodes of different components (003's "roadmap tree").
    pub tree: bool,
    /// Largest inflation (metres) of the certified motion checks.
    pub certify_inflation: f64,
}

impl Default for SuperGraphParams {
    fn default() -> Self {
        SuperGraphParams {
            prm: VisibilityPrmSettings::default(),
            stationary: true,
            tree: false,
            certify_inflation: FastChecker::CERTIFY_INFLATION,
        }
    }
}

/// A node of the super graph.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SuperNode {
    /// State of the super space (common, part 0, part 1).
    pub q: Vec<f64>,
    /// The elementary nodes merged.
    pub from: [u32; 2],
    /// The part whose elementary node gave the common variables.
    pub common_from: u8,
}

/// Counts and times of a build.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SuperGraphStats {
    pub node_candidates: usize,
    pub edge_candidates: usize,
    /// Candidate edges skipped because both ends were already connected (tree mode).
    pub edges_skipped: usize,
    pub components: usize,
    pub elementary_millis: [f64; 2],
    pub nodes_millis: f64,
    pub edges_millis: f64,
    pub total_millis: f64,
}

/// The composed roadmap (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SuperGraph {
    pub decomposition: Decomposition,
    pub params: SuperGraphParams,
    /// The world configuration of the variables outside each space during the build.
    pub base: Vec<f64>,
    pub elementary: [Roadmap; 2],
    pub nodes: Vec<SuperNode>,
    /// Undirected certified edges `(a, b)`, `a < b`, sorted.
    pub edges: Vec<(u32, u32)>,
    pub stats: SuperGraphStats,
}

fn validator(
    world: &CollisionWorld,
    space: &JointSpace,
    inflation: f64,
) -> SpaceValidator<FastChecker> {
    let checker = space_checker(world, space);
    SpaceValidator::new(space.clone(), world, checker, ANGULAR, LINEAR)
        .with_certification(Some(inflation))
}

impl SuperGraph {
    /// The super space in `world` (common, part 0, part 1) with the other variables at `base`.
    pub fn space(&self, world: &CollisionWorld, base: Vec<f64>) -> Result<JointSpace, PlanError> {
        JointSpace::new(world, &self.decomposition.super_vars(), base)
    }

    /// Neighbours of every node.
    pub fn neighbours(&self) -> Vec<Vec<u32>> {
        let mut n = vec![Vec::new(); self.nodes.len()];
        for &(a, b) in &self.edges {
            n[a as usize].push(b);
            n[b as usize].push(a);
        }
        n
    }

    /// True when the edge `a – b` exists (either order).
    pub fn has_edge(&self, a: u32, b: u32) -> bool {
        self.edges.binary_search(&(a.min(b), a.max(b))).is_ok()
    }

    /// Elementary nodes `a`, `b` of roadmap `k` are linked: an edge, or (stationary moves) the
    /// same node.
    pub fn elementary_linked(&self, k: usize, a: u32, b: u32) -> bool {
        (self.params.stationary && a == b) || self.elementary[k].has_edge(a, b)
    }
}

/// Builds the super graph of `dec` in the roadmap world of `world` ([`roadmap_world`]), other
/// variables at `base` (a full world configuration: the rest pose of the arms, the fingers).
/// Each elementary roadmap is seeded with `base` itself. Deterministic per `params.prm.seed`.
pub fn build_super_graph(
    world: &CollisionWorld,
    dec: &Decomposition,
    base: &[f64],
    params: &SuperGraphParams,
    term: &mut Termination,
) -> Result<SuperGraph, PlanError> {
    let t0 = Instant::now();
    params.prm.check()?;
    if !(params.certify_inflation.is_finite() && params.certify_inflation > 0.0) {
        return Err(PlanError::InvalidInput(
            "certify_inflation must be finite and > 0".into(),
        ));
    }
    let world = roadmap_world(world);
    let mut stats = SuperGraphStats::default();
    let nc = dec.common.len();

    // Elementary roadmaps.
    let mut elementary: Vec<Roadmap> = Vec::with_capacity(2);
    for k in 0..2 {
        let te = Instant::now();
        let wk = dec.elementary_world(&world, k);
        let space = JointSpace::new(&wk, &dec.elementary_vars(k), base.to_vec())?;
        let mut v = validator(&wk, &space, params.certify_inflation);
        let seed = space.from_world(base);
        let prm = VisibilityPrmSettings {
            seed: params.prm.seed.wrapping_add(k as u64),
            ..params.prm
        };
        elementary.push(visibility_prm(&mut v, &prm, &[seed], term)?);
        stats.elementary_millis[k] = te.elapsed().as_secs_f64() * 1e3;
    }
    let elementary: [Roadmap; 2] = [elementary.remove(0), elementary.remove(0)];

    // Super nodes.
    let tn = Instant::now();
    let space = JointSpace::new(&world, &dec.super_vars(), base.to_vec())?;
    let part_worlds = [dec.part_world(&world, 0), dec.part_world(&world, 1)];
    let mut part_v = [
        validator(&part_worlds[0], &space, params.certify_inflation),
        validator(&part_worlds[1], &space, params.certify_inflation),
    ];
    let mixed_world = dec.mixed_world(&world);
    let mut mixed_v = validator(&mixed_world, &space, params.certify_inflation);
    let (n0, n1) = (elementary[0].nodes.len(), elementary[1].nodes.len());
    let mut index = vec![u32::MAX; n0 * n1 * 2];
    let mut nodes: Vec<SuperNode> = Vec::new();
    for i in 0..n0 {
        for j in 0..n1 {
            let (x0, x1) = (&elementary[0].nodes[i], &elementary[1].nodes[j]);
            for c in 0..2usize {
                let torso = if c == 0 { &x0[..nc] } else { &x1[..nc] };
                if c == 1 && x0[..nc] == x1[..nc] {
                    continue; // same torso: one node
                }
                let mut q = torso.to_vec();
                q.extend_from_slice(&x0[nc..]);
                q.extend_from_slice(&x1[nc..]);
                stats.node_candidates += 1;
                // Part c is as checked in R_c; the other part against the rest.
                if part_v[1 - c].is_state_valid(&q) {
                    index[(i * n1 + j) * 2 + c] = nodes.len() as u32;
                    nodes.push(SuperNode {
                        q,
                        from: [i as u32, j as u32],
                        common_from: c as u8,
                    });
                }
            }
        }
    }
    stats.nodes_millis = tn.elapsed().as_secs_f64() * 1e3;

    // Super edges.
    let te = Instant::now();
    let linked = |k: usize| -> Vec<(u32, u32)> {
        let n = elementary[k].nodes.len() as u32;
        let mut l: Vec<(u32, u32)> = Vec::new();
        for &(a, b) in &elementary[k].edges {
            l.push((a, b));
            l.push((b, a));
        }
        if params.stationary {
            l.extend((0..n).map(|a| (a, a)));
        }
        l
    };
    let (l0, l1) = (linked(0), linked(1));
    let mut seen: HashSet<(u32, u32)> = HashSet::new();
    let mut edges: Vec<(u32, u32)> = Vec::new();
    let mut uf = UnionFind::new(nodes.len());
    'outer: for &(i, i2) in &l0 {
        // Each undirected pair of R₀ once: the reverse orientation of R₁ covers the rest.
        if i > i2 {
            continue;
        }
        for &(j, j2) in &l1 {
            if i == i2 && j == j2 {
                continue;
            }
            for c in 0..2usize {
                let x = index[(i as usize * n1 + j as usize) * 2 + c];
                if x == u32::MAX {
                    continue;
                }
                for c2 in 0..2usize {
                    let y = index[(i2 as usize * n1 + j2 as usize) * 2 + c2];
                    if y == u32::MAX || x == y || !seen.insert((x.min(y), x.max(y))) {
                        continue;
                    }
                    if term.should_stop_now() {
                        break 'outer;
                    }
                    if params.tree && uf.find(x) == uf.find(y) {
                        stats.edges_skipped += 1;
                        continue;
                    }
                    stats.edge_candidates += 1;
                    let (qx, qy) = (&nodes[x as usize].q, &nodes[y as usize].q);
                    let ok = if c == c2 {
                        part_v[1 - c].is_motion_valid(qx, qy)
                    } else {
                        mixed_v.is_motion_valid(qx, qy)
                    };
                    if ok {
                        edges.push((x.min(y), x.max(y)));
                        uf.union(x, y);
                    }
                }
            }
        }
    }
    if let Some(reason) = term.reason() {
        return Err(PlanError::stopped(reason, Default::default()));
    }
    edges.sort_unstable();
    stats.edges_millis = te.elapsed().as_secs_f64() * 1e3;
    let mut roots: Vec<u32> = (0..nodes.len() as u32).map(|i| uf.find(i)).collect();
    roots.sort_unstable();
    roots.dedup();
    stats.components = roots.len();
    stats.total_millis = t0.elapsed().as_secs_f64() * 1e3;
    Ok(SuperGraph {
        decomposition: dec.clone(),
        params: *params,
        base: base.to_vec(),
        elementary,
        nodes,
        edges,
        stats,
    })
}
