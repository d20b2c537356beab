//! RRT-Connect: J. J. Kuffner and S. M. LaValle, "RRT-Connect: An efficient approach to
//! single-query path planning", ICRA 2000. Two trees, one rooted at the start and one at the
//! goals, alternately EXTEND toward a uniform random sample and CONNECT (repeated EXTEND) toward
//! the state the other tree just added. The goal tree is seeded with every valid goal state, so
//! a path to any of a set of goals is found (as MotionBenchMaker/VAMP problems require).

use std::time::Instant;

use rand::SeedableRng;

use crate::collision::{CollisionWorld, FastChecker, SegmentScreen};
use crate::planning::base::halton::Halton;
use crate::planning::base::shortcut::{simplify, ShortcutSettings};
use crate::planning::base::validity::{space_checker, SegmentChecker, SpaceValidator};
use crate::planning::{
    DomainPretest, JointSpace, PlanError, PlanResult, PlanStats, PlannerRng, Termination, Tree,
    NO_PARENT,
};

/// Settings of [`RrtConnect`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RrtConnectSettings {
    /// Largest step of one EXTEND, in the space's distance. `None`: 0.2 × the space's maximum
    /// extent (OMPL's default).
    pub range: Option<f64>,
    /// Motion validation resolution for revolute variables, radians per checked step.
    pub angular_resolution: f64,
    /// Motion validation resolution for prismatic variables, metres per checked step.
    pub linear_resolution: f64,
    /// Try the straight segment from the start to each goal before growing trees.
    pub direct_connect: bool,
    /// Simplify every solution (see [`crate::planning::base::shortcut`]); `None` returns the raw path.
    pub shortcut: Option<ShortcutSettings>,
    /// Re-validate the raw path before returning it. Its segments are exactly the tree edges
    /// already validated with the same checker and resolution, so this is a safety net only.
    pub revalidate: bool,
    /// Certified motion checks: every segment is proven collision-free as a continuous motion
    /// (swept-volume bounds, spheres inflated by at most this many metres in the first pass;
    /// see [`crate::collision::SphereChecker::segment_certified`]) when the checker can;
    /// otherwise, or with `None`, states are checked at the resolutions.
    pub certify: Option<f64>,
    /// Dynamic-domain sampling (Yershova, Jaillet, Siméon & LaValle, ICRA 2005): a state whose
    /// EXTEND hit an obstacle gets this radius (shrinking by 0.01 % per further failure, never
    /// below the range; growing by 0.01 % per success), and samples farther than that from
    /// their nearest state are skipped without any collision check. `None`: plain RRT-Connect.
    pub dynamic_domain: Option<f64>,
    /// Extend the tree with fewer states each iteration (instead of alternating trees).
    pub balance: bool,
    /// Lazy certification (with `certify` and a checker that has a screening pass, see
    /// [`SegmentChecker::segment_screened`]): EXTEND adds a state when the first, uniform pass
    /// of the certified check finds the motion's states free, and a motion that pass does not
    /// already prove free is certified only when it lies on a found path (lazy collision
    /// checking in the manner of Bohlin & Kavraki's Lazy PRM, ICRA 2000, applied to the
    /// certificate's refinement only). An edge that fails is removed with its subtree
    /// ([`Tree::remove_subtree`]) and the search goes on. A path edge's certification refines
    /// from its screening pass ([`SpaceValidator::certify_screened`]) instead of running that
    /// pass again. Every returned path is fully certified either way; `false` (the default,
    /// here and in `bench mbm`; `--lazy-certify` turns it on) certifies every edge when it is
    /// added. Measured with the linear certificate (callgrind, 15 Panda MotionBenchMaker
    /// problems per set, search only, lazy against eager): cage −12.6 %, bookshelf_small
    /// −7.2 %, table_pick −5.2 %, box −4.8 %, table_under_pick −3.6 %, bookshelf_thin −2.4 %,
    /// bookshelf_tall −0.6 % (rerunning the screening pass instead made the easy sets 4–12 %
    /// slower); with the chord certificate, all 699 Panda problems +0.7 % for lazy, Baxter
    /// (30 problems, 3 seeds) +15 % (its searches meet lazily accepted edges that fail).
    pub lazy: bool,
    /// Where EXTEND's samples come from.
    pub sampler: Sampler,
}

/// The sample source of [`RrtConnect`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampler {
    /// Uniform draws within the bounds from the seeded generator ([`PlannerRng`]): another
    /// seed, another search.
    #[default]
    Uniform,
    /// The Halton sequence within the bounds, from its first point, the same for every
    /// problem and seed ([`crate::planning::base::halton`]; VAMP's default sampler, which it also restarts per
    /// problem). The seed still drives the shortcutting. On MotionBenchMaker's Panda cage set
    /// it needs 634 iterations (median) where seeds 1–4 of the uniform sampler need 858–1 064;
    /// started one point later it needs 830, so the gain belongs to these problems and the
    /// sequence's first points, not to the method (README, "Where the time goes against
    /// VAMP"); on 180 of Baxter's problems it is slower (median 4.8 against 3.7 ms, a heavier
    /// tail; its samples are not drawn in the fused f32 loop of [`PlannerRng`]). Offered for
    /// comparisons with VAMP and for runs that must not depend on a seed.
    Halton,
}

impl Default for RrtConnectSettings {
    fn default() -> Self {
        RrtConnectSettings {
            range: None,
            angular_resolution: 0.5f64.to_radians(),
            linear_resolution: 0.005,
            direct_connect: true,
            shortcut: Some(ShortcutSettings::default()),
            revalidate: true,
            certify: None,
            dynamic_domain: None,
            balance: false,
            lazy: false,
            sampler: Sampler::Uniform,
        }
    }
}

impl RrtConnectSettings {
    /// Checks the resolutions and returns the EXTEND range for `space` (explicit, or 0.2 × the
    /// space's maximum extent).
    pub fn checked_range(&self, space: &JointSpace) -> Result<f64, PlanError> {
        self.validate()?;
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let range = match self.range {
            Some(r) => r,
            None => 0.2 * space.max_extent(),
        };
        if !pos(range) {
            return Err(PlanError::InvalidInput(
                "the space has no extent (all bounds equal)".into(),
            ));
        }
        Ok(range)
    }

    /// Checks the settings that do not depend on the space (resolutions, EXTEND range,
    /// dynamic-domain radius, certification inflation), so that a caller can refuse bad settings
    /// before any work.
    pub fn validate(&self) -> Result<(), PlanError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.angular_resolution) || !pos(self.linear_resolution) {
            return Err(PlanError::InvalidInput(
                "resolutions must be finite and > 0".into(),
            ));
        }
        if let Some(r) = self.dynamic_domain {
            if !pos(r) {
                return Err(PlanError::InvalidInput(format!(
                    "dynamic_domain radius must be finite and > 0, got {r}"
                )));
            }
        }
        if let Some(d) = self.certify {
            if !pos(d) {
                return Err(PlanError::InvalidInput(format!(
                    "certify (largest inflation) must be finite and > 0 metres, got {d}"
                )));
            }
        }
        if let Some(r) = self.range.filter(|&r| !pos(r)) {
            return Err(PlanError::InvalidInput(format!(
                "range must be finite and > 0, got {r}"
            )));
        }
        Ok(())
    }
}

/// Outcome of one EXTEND step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Extend {
    Trapped,
    Advanced(u32),
    Reached(u32),
}

/// The RRT-Connect planner over a [`JointSpace`], validating motions with a collision checker
/// (by default the conservative [`FastChecker`]). Reusable: trees and buffers are kept between
/// queries.
pub struct RrtConnect<C: SegmentChecker = FastChecker> {
    validator: SpaceValidator<C>,
    settings: RrtConnectSettings,
    range: f64,
    trees: [Tree; 2],
    q_rand: Vec<f64>,
    q_new: Vec<f64>,
    q_target: Vec<f64>,
    idx: Vec<u32>,
    screens: Screens,
}

/// The screening records of the edges lazy certification accepted unproven (see
/// [`RrtConnectSettings::lazy`]): such an edge's tree tag ([`Tree::mark_unproven_tagged`]) is
/// its record's index in `spans` plus one, so that certifying it on a found path refines only
/// ([`SpaceValidator::certify_screened`]) instead of running the screening pass again.
#[derive(Debug, Default)]
pub(super) struct Screens {
    entries: Vec<(usize, u32)>,
    /// (first entry, count) per record.
    spans: Vec<(u32, u32)>,
}

impl Screens {
    fn clear(&mut self) {
        self.entries.clear();
        self.spans.clear();
    }

    /// Screens the motion `a → b` lazily; on [`SegmentScreen::Tight`] also returns the tag of
    /// its record.
    #[inline]
    fn screen<C: SegmentChecker>(
        &mut self,
        v: &mut SpaceValidator<C>,
        a: &[f64],
        b: &[f64],
    ) -> (SegmentScreen, u32) {
        let first = self.entries.len();
        let s = v.screen_motion_recorded(a, b, &mut self.entries);
        if s != SegmentScreen::Tight {
            self.entries.truncate(first);
            return (s, 0);
        }
        let count = self.entries.len() - first;
        self.spans.push((first as u32, count as u32));
        (s, self.spans.len() as u32)
    }

    /// The record of `tag` (`None`: none kept).
    fn get(&self, tag: u32) -> Option<&[(usize, u32)]> {
        let &(first, count) = self.spans.get((tag as usize).checked_sub(1)?)?;
        self.entries.get(first as usize..(first + count) as usize)
    }
}

impl RrtConnect<FastChecker> {
    /// A planner for `space` in `world` with a [`FastChecker`] of that world.
    pub fn new(
        space: JointSpace,
        world: &CollisionWorld,
        settings: RrtConnectSettings,
    ) -> Result<Self, PlanError> {
        let checker = space_checker(world, &space);
        RrtConnect::with_checker(space, world, checker, settings)
    }
}

impl<C: SegmentChecker> RrtConnect<C> {
    /// A planner validating with `checker` (built for `world`).
    pub fn with_checker(
        space: JointSpace,
        world: &CollisionWorld,
        checker: C,
        settings: RrtConnectSettings,
    ) -> Result<Self, PlanError> {
        let range = settings.checked_range(&space)?;
        let dim = space.dim();
        let weights = space.weights().to_vec();
        Ok(RrtConnect {
            validator: SpaceValidator::new(
                space,
                world,
                checker,
                settings.angular_resolution,
                settings.linear_resolution,
            )
            .with_certification(settings.certify),
            settings,
            range,
            trees: [Tree::new(&weights), Tree::new(&weights)],
            q_rand: vec![0.0; dim],
            q_new: vec![0.0; dim],
            q_target: vec![0.0; dim],
            idx: Vec::new(),
            screens: Screens::default(),
        })
    }

    pub fn space(&self) -> &JointSpace {
        self.validator.space()
    }

    pub fn settings(&self) -> &RrtConnectSettings {
        &self.settings
    }

    /// The EXTEND step length in use.
    pub fn range(&self) -> f64 {
        self.range
    }

    /// The validator (e.g. to check other paths with the same checker and resolution).
    pub fn validator(&mut self) -> &mut SpaceValidator<C> {
        &mut self.validator
    }

    /// Plans from `start` to any of `goals` (states of the space; values at most
    /// [`Limits::TOLERANCE`](crate::model::Limits::TOLERANCE) outside the bounds are clamped
    /// into them, see [`JointSpace::snap_to_bounds`]). Invalid goals are skipped;
    /// the query fails cleanly when the start or every goal is invalid, or when `term` fires.
    /// The raw path is re-validated at the configured resolution, then simplified when the
    /// settings ask for it. All randomness comes from `seed`.
    pub fn plan(
        &mut self,
        start: &[f64],
        goals: &[Vec<f64>],
        term: &mut Termination,
        seed: u64,
    ) -> Result<PlanResult, PlanError> {
        let t0 = Instant::now();
        self.validator.reset_certify_stats();
        let checks0 = self.validator.checks();
        let segments0 = self.validator.segments();
        let mut rng = PlannerRng::seed_from_u64(seed);
        let mut stats = PlanStats::default();

        // Values at most `Limits::TOLERANCE` outside the bounds are clamped into them (the
        // returned path starts at the clamped start and ends at a clamped goal).
        let start = self.validator.space().snap_to_bounds(start).into_owned();
        let goals: Vec<Vec<f64>> = goals
            .iter()
            .map(|g| self.validator.space().snap_to_bounds(g).into_owned())
            .collect();
        let (start, goals) = (start.as_slice(), goals.as_slice());
        if let Some(why) = self.validator.invalidity(start) {
            return Err(PlanError::InvalidStart { reason: why });
        }
        if goals.is_empty() {
            return Err(PlanError::InvalidGoal {
                count: 0,
                reason: "no goal given".into(),
            });
        }
        let mut goal_ids: Vec<usize> = Vec::with_capacity(goals.len());
        let mut first_reason = None;
        for (k, g) in goals.iter().enumerate() {
            match self.validator.invalidity(g) {
                None => goal_ids.push(k),
                Some(why) => {
                    first_reason.get_or_insert_with(|| format!("goal {k}: {why}"));
                }
            }
        }
        if goal_ids.is_empty() {
            return Err(PlanError::InvalidGoal {
                count: goals.len(),
                reason: first_reason.unwrap_or_default(),
            });
        }

        let range = self.range;
        let RrtConnect {
            validator,
            trees,
            q_rand,
            q_new,
            q_target,
            idx,
            settings,
            screens,
            ..
        } = self;
        let [ts, tg] = trees;
        ts.clear();
        tg.clear();
        screens.clear();
        ts.add(start, NO_PARENT);
        for &k in &goal_ids {
            tg.add(&goals[k], NO_PARENT);
        }

        let mut found: Option<(u32, u32)> = None; // (start-tree node, goal-tree node)
        if settings.direct_connect {
            for (root, &k) in goal_ids.iter().enumerate() {
                if validator.is_motion_valid(start, &goals[k]) {
                    found = Some((0, root as u32));
                    break;
                }
            }
        }
        // The f32 pretests of the fused dynamic-domain sampling, one per tree (state 0 is
        // fixed from here on).
        let pretests = if settings.dynamic_domain.is_some() && settings.balance {
            let space = validator.space();
            let pretest = |t: &Tree| {
                DomainPretest::new(space.lower(), space.upper(), t.state(0), t.weights())
            };
            [pretest(ts), pretest(tg)]
        } else {
            [None, None]
        };
        let mut halton = match settings.sampler {
            Sampler::Uniform => None,
            Sampler::Halton => Some(Halton::new(validator.space().dim())?),
        };
        let mut iterations = 0u64;
        let mut start_side = true; // the tree extended toward the sample this iteration
                                   // Per tree (start, goal): its size when last seen and the iteration it last grew at.
        let mut grew: [(usize, u64); 2] = [(ts.len(), 0), (tg.len(), 0)];
        while found.is_none() {
            if term.should_stop() {
                stats.iterations = iterations;
                stats.start_tree_size = ts.len();
                stats.goal_tree_size = tg.len();
                return Err(stopped(validator, stats, (t0, checks0, segments0), term));
            }
            iterations += 1;
            if settings.balance {
                start_side = ts.len() <= tg.len();
            }
            let (ta, tb) = if start_side {
                (&mut *ts, &mut *tg)
            } else {
                (&mut *tg, &mut *ts)
            };
            if settings.dynamic_domain.is_some() {
                let g = &mut grew[usize::from(!start_side)];
                if ta.len() != g.0 {
                    *g = (ta.len(), iterations);
                } else if iterations - g.1 > DYNAMIC_DOMAIN_STALL {
                    ta.reset_radii();
                    g.1 = iterations;
                }
            }
            // Samples outside the ball around `ta`'s state 0 lie outside every domain of `ta`
            // (most of them: see `Tree::outside_every_domain`) and are skipped without a
            // nearest-neighbour query. With balanced trees the side stays the same until a
            // tree grows, so they are drawn and skipped in one fused loop, each still counted
            // as an iteration. Same draws, same search as one sample per iteration.
            let ball = settings.dynamic_domain.and_then(|_| ta.domain_ball());
            if let Some(h) = halton.as_mut() {
                // The same skipping as the uniform draws below: one sample per iteration, and
                // with balanced trees the samples the domains skip are drawn in one loop (the
                // side stays until a tree grows), each counted as an iteration.
                let space = validator.space();
                let (lo, hi) = (space.lower(), space.upper());
                let max_draws = match &ball {
                    Some(_) if settings.balance => 1 + term.quiet_iterations(),
                    _ => 1,
                };
                let mut draws = 0;
                let mut inside = false;
                while draws < max_draws {
                    draws += 1;
                    h.next_in(lo, hi, q_rand);
                    if !ball.as_ref().is_some_and(|b| b.excludes(q_rand)) {
                        inside = true;
                        break;
                    }
                }
                term.count_quiet(draws - 1);
                iterations += draws - 1;
                if !inside {
                    if !settings.balance {
                        start_side = !start_side;
                    }
                    continue;
                }
            } else if let (Some(ball), false) = (ball, settings.balance) {
                validator.space().sample_uniform_fast(&mut rng, q_rand);
                if ball.excludes(q_rand) {
                    start_side = !start_side;
                    continue;
                }
            } else if let Some(ball) = ball {
                let space = validator.space();
                let quiet = term.quiet_iterations();
                let (draws, inside) = rng.fill_uniform_until_inside(
                    space.lower(),
                    space.upper(),
                    &ball,
                    pretests[usize::from(!start_side)].as_ref(),
                    1 + quiet,
                    q_rand,
                );
                term.count_quiet(draws - 1);
                iterations += draws - 1;
                if !inside {
                    continue;
                }
            } else {
                validator.space().sample_uniform_fast(&mut rng, q_rand);
            }
            let mut lazy = settings.lazy.then_some(&mut *screens);
            let grown = match settings.dynamic_domain {
                Some(r0) => extend_dynamic_domain(
                    ta,
                    validator,
                    range,
                    r0,
                    q_rand,
                    q_new,
                    lazy.as_deref_mut(),
                ),
                None => extend_with(ta, validator, range, q_rand, q_new, lazy.as_deref_mut()),
            };
            match grown {
                Extend::Trapped => {}
                Extend::Advanced(i) | Extend::Reached(i) => {
                    q_target.copy_from_slice(ta.state(i));
                    if let Some(j) = connect_with(tb, validator, range, q_target, q_new, lazy) {
                        found = Some(if start_side { (i, j) } else { (j, i) });
                    }
                }
            }
            start_side = !start_side;
            // Lazy certification: the found path's unproven edges are certified now; one that
            // fails goes with its subtree and the search continues.
            if let (Some((s, g)), true) = (found, settings.lazy) {
                let removed_s = certify_branch(ts, s, validator, idx, screens);
                let removed = if removed_s > 0 {
                    removed_s
                } else {
                    certify_branch(tg, g, validator, idx, screens)
                };
                if removed > 0 {
                    stats.lazy_removed += removed as u64;
                    found = None;
                }
            }
        }
        let Some((s, g)) = found else {
            return Err(PlanError::InvalidInput(
                "internal: search ended without a solution".into(),
            ));
        };
        let path = join_trees(ts, s, tg, g, idx);
        let goal_index = goal_ids[tg.root_of(g) as usize];
        stats.iterations = iterations;
        stats.start_tree_size = ts.len();
        stats.goal_tree_size = tg.len();
        let counters = (t0, checks0, segments0);
        let (path, stats) = finish(validator, path, settings, stats, counters, &mut rng, term)?;
        Ok(PlanResult {
            path,
            goal_index,
            stats,
        })
    }
}

/// The path start root … `s` (in `ts`), then `g` … goal root (in `tg`), without repeating a state
/// the two trees share.
pub(super) fn join_trees(
    ts: &Tree,
    s: u32,
    tg: &Tree,
    g: u32,
    idx: &mut Vec<u32>,
) -> Vec<Vec<f64>> {
    let mut path: Vec<Vec<f64>> = Vec::new();
    ts.path_from_root(s, idx);
    path.extend(idx.iter().map(|&i| ts.state(i).to_vec()));
    tg.path_from_root(g, idx);
    for (n, &i) in idx.iter().rev().enumerate() {
        let q = tg.state(i);
        if n == 0 && path.last().is_some_and(|l| l.as_slice() == q) {
            continue;
        }
        path.push(q.to_vec());
    }
    path
}

/// The common end of every tree planner: re-validates the raw `path` at the validator's
/// resolution (when the settings ask for it), fills the statistics (`counters`: the search's start
/// time and the validator's check and segment counts at that time), then simplifies the path.
pub(super) fn finish<C: SegmentChecker>(
    validator: &mut SpaceValidator<C>,
    mut path: Vec<Vec<f64>>,
    settings: &RrtConnectSettings,
    mut stats: PlanStats,
    (t0, checks0, segments0): (Instant, u64, u64),
    rng: &mut impl rand::Rng,
    term: &mut Termination,
) -> Result<(Vec<Vec<f64>>, PlanStats), PlanError> {
    // The returned path is re-validated at the resolution: a simplified path by `simplify`
    // (which restores the raw path if that fails); the raw path here when it is returned as is.
    stats.length_raw = validator.space().path_length(&path);
    stats.vertices_raw = path.len();
    let mut must_check_raw = settings.revalidate;
    if let Some(sc) = settings.shortcut {
        stats.time = t0.elapsed();
        let t1 = Instant::now();
        let st = simplify(validator, &mut path, &sc, rng, term);
        stats.simplify_time = t1.elapsed();
        // Shortcuts were validated and the result re-validated; a reverted (raw) path and a path
        // too short to simplify are checked below.
        must_check_raw &= st.reverted || st.checked_whole == 0;
    }
    if must_check_raw {
        let t2 = Instant::now();
        let checked = validator.validate_path(&path);
        if settings.shortcut.is_some() {
            stats.simplify_time += t2.elapsed();
        }
        if let Err(k) = checked {
            stats.collision_checks = validator.checks() - checks0;
            stats.segments_checked = validator.segments() - segments0;
            stats.time = t0.elapsed();
            return Err(PlanError::PathInvalid {
                segment: k,
                stats: Box::new(stats),
            });
        }
    }
    if settings.shortcut.is_none() {
        stats.time = t0.elapsed();
    }
    stats.collision_checks = validator.checks() - checks0;
    stats.segments_checked = validator.segments() - segments0;
    stats.certification = validator.certify_stats();
    stats.length_simplified = validator.space().path_length(&path);
    stats.vertices_simplified = path.len();
    Ok((path, stats))
}

/// The statistics of a search that was stopped.
pub(super) fn stopped<C: SegmentChecker>(
    validator: &SpaceValidator<C>,
    mut stats: PlanStats,
    (t0, checks0, segments0): (Instant, u64, u64),
    term: &Termination,
) -> PlanError {
    stats.collision_checks = validator.checks() - checks0;
    stats.segments_checked = validator.segments() - segments0;
    stats.certification = validator.certify_stats();
    stats.time = t0.elapsed();
    let reason = term
        .reason()
        .unwrap_or(crate::planning::StopReason::Requested);
    PlanError::stopped(reason, stats)
}

/// Certifies the unproven edges (see [`RrtConnectSettings::lazy`]) from a root of `tree` down
/// to state `i` with the full certified check, root side first. Returns 0 when all are proven
/// now; otherwise the first that fails is removed with its subtree and the number of states
/// removed is returned (`i` is then gone and indices of `tree` have shifted).
fn certify_branch<C: SegmentChecker>(
    tree: &mut Tree,
    i: u32,
    v: &mut SpaceValidator<C>,
    idx: &mut Vec<u32>,
    screens: &Screens,
) -> usize {
    tree.path_from_root(i, idx);
    for w in 1..idx.len() {
        let (p, c) = (idx[w - 1], idx[w]);
        let Some(tag) = tree.unproven_tag(c) else {
            continue;
        };
        let ok = match screens.get(tag) {
            Some(record) => v.certify_screened(tree.state(p), tree.state(c), record),
            None => v.is_motion_valid(tree.state(p), tree.state(c)),
        };
        if ok {
            tree.mark_proven(c);
        } else {
            return tree.remove_subtree(c);
        }
    }
    0
}

/// CONNECT (Kuffner & LaValle 2000): EXTEND toward `target` until it is reached (its index) or
/// the tree is trapped (`None`).
pub(super) fn connect<C: SegmentChecker>(
    tree: &mut Tree,
    v: &mut SpaceValidator<C>,
    range: f64,
    target: &[f64],
    q_new: &mut [f64],
) -> Option<u32> {
    connect_with(tree, v, range, target, q_new, None)
}

/// [`connect`], lazily checked when `lazy` (see [`RrtConnectSettings::lazy`]).
fn connect_with<C: SegmentChecker>(
    tree: &mut Tree,
    v: &mut SpaceValidator<C>,
    range: f64,
    target: &[f64],
    q_new: &mut [f64],
    mut lazy: Option<&mut Screens>,
) -> Option<u32> {
    // One nearest-neighbour query per CONNECT, not one per step: a step that advances adds the
    // state `range` along the straight line from the nearest state (at distance `d`) toward
    // `target`, so the new state is at `d − range` from it (the space's distance is a norm),
    // nearer than every other state (all at least `d`) — it is the next step's nearest state.
    // Its squared distance is computed as the scan computes it (`Tree::dist_sq`), so the steps
    // are the ones of a query per step, bit for bit.
    let mut near = tree.nearest(target)?;
    loop {
        match extend_from(tree, v, range, near, target, q_new, lazy.as_deref_mut()) {
            Extend::Advanced(j) => near = (j, tree.dist_sq(j, target)),
            Extend::Reached(j) => return Some(j),
            Extend::Trapped => return None,
        }
    }
}

/// Share by which a dynamic-domain radius shrinks after a failed EXTEND and grows after a
/// successful one (VAMP's and Yershova et al.'s α).
const DYNAMIC_DOMAIN_ALPHA: f64 = 1e-4;

/// Iterations (samples drawn, the ones the domains skip included) a tree may go without
/// growing before its dynamic-domain radii are reset to infinite. Radii never fall below the
/// range, but a small tree whose every state sits at that floor accepts almost no sample in a
/// high-dimensional space (14-D Baxter problems drew 10⁸ samples in 10 s, none accepted): the
/// restart keeps the search probabilistically complete, as plain RRT-Connect is. Runs that
/// never stall this long are unchanged.
const DYNAMIC_DOMAIN_STALL: u64 = 1 << 16;

/// EXTEND with dynamic-domain sampling (see [`RrtConnectSettings::dynamic_domain`]): a sample
/// outside its nearest state's radius is skipped (`Trapped`, nothing checked). The caller has
/// already skipped the samples [`Tree::domain_ball`] excludes.
#[inline]
fn extend_dynamic_domain<C: SegmentChecker>(
    tree: &mut Tree,
    v: &mut SpaceValidator<C>,
    range: f64,
    radius: f64,
    target: &[f64],
    q_new: &mut [f64],
    lazy: Option<&mut Screens>,
) -> Extend {
    let Some((near, d2)) = tree.nearest(target) else {
        return Extend::Trapped;
    };
    let r = tree.radius(near);
    if d2 > r * r {
        return Extend::Trapped;
    }
    let grown = extend_from(tree, v, range, (near, d2), target, q_new, lazy);
    if grown == Extend::Trapped {
        let shrunk = if r.is_finite() {
            (r * (1.0 - DYNAMIC_DOMAIN_ALPHA)).max(range)
        } else {
            radius
        };
        tree.set_radius(near, shrunk);
    } else if r.is_finite() {
        tree.set_radius(near, r * (1.0 + DYNAMIC_DOMAIN_ALPHA));
    }
    grown
}

/// EXTEND (Kuffner & LaValle 2000): step from the nearest state of `tree` toward `target` by at
/// most `range`; add the new state when the motion to it is valid.
#[inline]
pub(super) fn extend<C: SegmentChecker>(
    tree: &mut Tree,
    v: &mut SpaceValidator<C>,
    range: f64,
    target: &[f64],
    q_new: &mut [f64],
) -> Extend {
    extend_with(tree, v, range, target, q_new, None)
}

/// [`extend`], lazily checked when `lazy` (see [`RrtConnectSettings::lazy`]).
#[inline]
fn extend_with<C: SegmentChecker>(
    tree: &mut Tree,
    v: &mut SpaceValidator<C>,
    range: f64,
    target: &[f64],
    q_new: &mut [f64],
    lazy: Option<&mut Screens>,
) -> Extend {
    let Some(nearest) = tree.nearest(target) else {
        return Extend::Trapped;
    };
    extend_from(tree, v, range, nearest, target, q_new, lazy)
}

/// The step of EXTEND from the state `near` (at squared distance `d2` from `target`).
#[inline]
fn extend_from<C: SegmentChecker>(
    tree: &mut Tree,
    v: &mut SpaceValidator<C>,
    range: f64,
    (near, d2): (u32, f64),
    target: &[f64],
    q_new: &mut [f64],
    lazy: Option<&mut Screens>,
) -> Extend {
    if d2 == 0.0 {
        return Extend::Reached(near);
    }
    let d = d2.sqrt();
    let reached = d <= range;
    if reached {
        q_new.copy_from_slice(target);
    } else {
        v.space()
            .interpolate(tree.state(near), target, range / d, q_new);
    }
    let (screen, tag) = match lazy {
        Some(screens) => screens.screen(v, tree.state(near), q_new),
        None if v.is_motion_valid(tree.state(near), q_new) => (SegmentScreen::Certified, 0),
        None => (SegmentScreen::Collides, 0),
    };
    if screen == SegmentScreen::Collides {
        return Extend::Trapped;
    }
    let i = tree.add(q_new, near);
    if screen == SegmentScreen::Tight {
        tree.mark_unproven_tagged(i, tag);
    }
    if reached {
        Extend::Reached(i)
    } else {
        Extend::Advanced(i)
    }
}
