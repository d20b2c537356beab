//! Visibility-PRM: T. Siméon, J.-P. Laumond and C. Nissoux, "Visibility-based probabilistic
//! roadmaps for motion planning", Advanced Robotics 14(6), 2000 — the compact PRM paper 003 §V-A
//! builds its elementary roadmaps with (ref. \[19\]).
//!
//! Two kinds of nodes: *guards*, no two of which see each other (the straight segment between
//! them is not free), and *connectors*, each seeing guards of at least two connected components
//! and joining them. A free sample that sees no guard becomes a guard; one that sees guards of two
//! or more components becomes a connector with an edge to one visible guard of each of them
//! (the original joins exactly two; joining every component it sees only merges sooner); any other
//! sample is dropped. The construction stops after [`VisibilityPrmSettings::max_failures`] free
//! samples in a row added no guard (Siméon et al.'s `M`: `1/M` estimates the fraction of the
//! free space no guard sees), or at the node or sample bound. Every edge is a segment the
//! [`SpaceValidator`] accepted — with the planners' [`FastChecker`](crate::collision::FastChecker)
//! a certified continuous motion. Deterministic per seed.

use rand::SeedableRng;
use serde::{Deserialize, Serialize};

use crate::planning::{PlanError, PlannerRng, SegmentChecker, SpaceValidator, Termination};

/// Settings of [`visibility_prm`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VisibilityPrmSettings {
    /// Nodes (guards and connectors) at most.
    pub max_nodes: usize,
    /// Stop after this many free samples in a row added no guard (`M` of Siméon et al.).
    pub max_failures: usize,
    /// Samples drawn at most, free or not.
    pub max_samples: usize,
    pub seed: u64,
}

impl Default for VisibilityPrmSettings {
    /// 50 nodes per roadmap as in 003 §VI ("two elementary roadmaps … each one containing 50
    /// nodes"), M = 100, at most 20 000 samples.
    fn default() -> Self {
        VisibilityPrmSettings {
            max_nodes: 50,
            max_failures: 100,
            max_samples: 20_000,
            seed: 1,
        }
    }
}

impl VisibilityPrmSettings {
    /// Checks the bounds (all > 0).
    pub fn check(&self) -> Result<(), PlanError> {
        if self.max_nodes == 0 || self.max_failures == 0 || self.max_samples == 0 {
            return Err(PlanError::InvalidInput(
                "max_nodes, max_failures and max_samples must be > 0".into(),
            ));
        }
        Ok(())
    }
}

/// What the construction did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PrmStats {
    pub samples: u64,
    pub free_samples: u64,
    /// Segments tested for visibility.
    pub visibility_checks: u64,
    pub guards: usize,
    pub connectors: usize,
    /// Connected components at the end.
    pub components: usize,
    pub millis: f64,
}

/// A roadmap: states of one space and the certified straight edges between them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Roadmap {
    /// States of the space the roadmap was built in.
    pub nodes: Vec<Vec<f64>>,
    /// True for guards, false for connectors.
    pub guard: Vec<bool>,
    /// Undirected edges `(a, b)` with `a < b`, sorted.
    pub edges: Vec<(u32, u32)>,
    pub stats: PrmStats,
}

impl Roadmap {
    /// True when the edge `a – b` exists (either order).
    pub fn has_edge(&self, a: u32, b: u32) -> bool {
        let e = (a.min(b), a.max(b));
        self.edges.binary_search(&e).is_ok()
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

    /// The connected component (smallest node index in it) of every node.
    pub fn components(&self) -> Vec<u32> {
        let mut uf = UnionFind::new(self.nodes.len());
        for &(a, b) in &self.edges {
            uf.union(a, b);
        }
        let mut label = vec![u32::MAX; self.nodes.len()];
        for i in 0..self.nodes.len() as u32 {
            let r = uf.find(i) as usize;
            if label[r] == u32::MAX {
                label[r] = i;
            }
        }
        (0..self.nodes.len() as u32)
            .map(|i| label[uf.find(i) as usize])
            .collect()
    }
}

/// Disjoint sets over `0..n` (path halving, union by index).
#[derive(Debug, Clone)]
pub(crate) struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    pub(crate) fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n as u32).collect(),
        }
    }

    pub(crate) fn push(&mut self) -> u32 {
        let i = self.parent.len() as u32;
        self.parent.push(i);
        i
    }

    pub(crate) fn find(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let g = self.parent[self.parent[i as usize] as usize];
            self.parent[i as usize] = g;
            i = g;
        }
        i
    }

    /// Joins the sets of `a` and `b`; false when they were one already.
    pub(crate) fn union(&mut self, a: u32, b: u32) -> bool {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra == rb {
            return false;
        }
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        self.parent[hi as usize] = lo;
        true
    }
}

/// Builds a Visibility-PRM (module docs) in the validator's space. `seeds` are tried as the
/// first samples (e.g. the rest configuration, so the roadmap holds it as a guard); invalid
/// seeds are skipped. Stops early (with the roadmap so far) when `term` fires.
pub fn visibility_prm<C: SegmentChecker>(
    v: &mut SpaceValidator<C>,
    settings: &VisibilityPrmSettings,
    seeds: &[Vec<f64>],
    term: &mut Termination,
) -> Result<Roadmap, PlanError> {
    settings.check()?;
    let t0 = std::time::Instant::now();
    let dim = v.space().dim();
    if let Some(s) = seeds.iter().find(|s| s.len() != dim) {
        return Err(PlanError::InvalidInput(format!(
            "a seed state has {} values for a {dim}-dimensional space",
            s.len()
        )));
    }
    let mut rng = PlannerRng::seed_from_u64(settings.seed);
    let mut map = Roadmap {
        nodes: Vec::new(),
        guard: Vec::new(),
        edges: Vec::new(),
        stats: PrmStats::default(),
    };
    let mut uf = UnionFind::new(0);
    // Guards of every component, by component root (a guard's root is refreshed on use).
    let mut guards: Vec<u32> = Vec::new();
    let mut q = vec![0.0; dim];
    let mut failures = 0usize;
    let mut seed_iter = seeds.iter();
    let mut visible: Vec<(u32, u32)> = Vec::new();
    while map.nodes.len() < settings.max_nodes
        && failures < settings.max_failures
        && (map.stats.samples as usize) < settings.max_samples
        && !term.should_stop()
    {
        map.stats.samples += 1;
        match seed_iter.next() {
            Some(s) => q.copy_from_slice(s),
            None => v.space().sample_uniform_fast(&mut rng, &mut q),
        }
        if !v.is_state_valid(&q) {
            continue;
        }
        map.stats.free_samples += 1;
        // One visible guard per component, components in order of their first guard.
        visible.clear();
        for &g in &guards {
            let root = uf.find(g);
            if visible.iter().any(|&(r, _)| r == root) {
                continue;
            }
            map.stats.visibility_checks += 1;
            if v.is_motion_valid(&q, &map.nodes[g as usize]) {
                visible.push((root, g));
            }
        }
        match visible.len() {
            0 => {
                let id = uf.push();
                map.nodes.push(q.clone());
                map.guard.push(true);
                guards.push(id);
                failures = 0;
            }
            1 => failures += 1,
            _ => {
                let id = uf.push();
                map.nodes.push(q.clone());
                map.guard.push(false);
                for &(_, g) in &visible {
                    map.edges.push((g.min(id), g.max(id)));
                    uf.union(g, id);
                }
                failures += 1;
            }
        }
    }
    map.edges.sort_unstable();
    map.stats.guards = guards.len();
    map.stats.connectors = map.nodes.len() - guards.len();
    let comps = map.components();
    let mut roots: Vec<u32> = comps.clone();
    roots.sort_unstable();
    roots.dedup();
    map.stats.components = roots.len();
    map.stats.millis = t0.elapsed().as_secs_f64() * 1e3;
    Ok(map)
}
