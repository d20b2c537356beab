//! N independent arms in one cell: one request, one timed plan on one clock, every motion
//! proven collision-free with all arms moving together (and what they hold).
//!
//! The planner chooses its method and reports which one succeeded:
//!
//! 1. **decoupled** ([`decoupled`]): every arm alone with RRT-Connect, then the phase-space
//!    schedule of paper 002 §V (Alg. 4) — fastest when it works. When some pair of paths has no
//!    monotone free path in its phase space (the search fails within its budget, the
//!    sequential fallback collides), no timing of these paths can work:
//! 2. **prioritized** ([`prioritized`]): the arms in a priority order, each planned in
//!    space-time around the earlier arms' timed motions ([`space_time`]), the order changed
//!    when an arm fails;
//! 3. **composite** ([`composite`]): RRT-Connect in the joint space of the arms in conflict
//!    only (the others then planned around them in space-time), and, as the complete fallback,
//!    in the joint space of every arm (the search of VAMP-MR's multi-arm cells).
//!
//! Every method produces a composite polyline ([`timed`] explains why a set of timed motions is
//! one); the polyline is certified segment by segment in the whole world with
//! [`crate::collision::FastChecker::motion_certified`] ([`cell`]), shortcut with the makespan
//! as the objective ([`shortcut`], mr-shortcut's two kinds of shortcuts), certified again, and
//! timed time-optimally on the polyline ([`crate::trajectory::timing`], TOPP-RA). Seeded and
//! single-threaded: the same problem and seed give the same plan.

pub mod cell;
pub mod composite;
pub mod decoupled;
pub mod prioritized;
pub mod problem;
pub mod result;
pub mod shortcut;
pub mod space_time;
pub mod timed;

use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use problem::{pose_goal, Arm, MultiArmProblem, MAX_ARMS, MAX_VARIABLES};
pub use result::{Attempt, MultiArmMethod, MultiArmPlan, MultiArmStats};
pub use shortcut::ShortcutReport;
pub use space_time::SpaceTimeSettings;

use crate::planning::planners::phase_space::PhaseSpaceSettings;
use crate::planning::{PlanError, PlanStats, RrtConnectSettings, StopReason, Termination};
use crate::trajectory::timing::{time_polyline, world_limits};
use cell::Cell;

/// Which methods may be used (all by default; the benchmark compares them alone).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Methods {
    pub decoupled: bool,
    pub prioritized: bool,
    pub composite: bool,
}

impl Default for Methods {
    fn default() -> Self {
        Methods {
            decoupled: true,
            prioritized: true,
            composite: true,
        }
    }
}

/// Settings of [`plan_multi_arm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiArmSettings {
    pub methods: Methods,
    /// RRT-Connect of the single-arm and composite searches.
    pub rrt: RrtConnectSettings,
    /// The phase-space scheduler (its iteration budget decides how soon "no schedule" is
    /// believed).
    pub phase: PhaseSpaceSettings,
    pub space_time: SpaceTimeSettings,
    /// RRT-Connect iterations of the composite search over the conflicting arms only (the
    /// search over all arms has the rest of the time).
    pub subset_iterations: u64,
    /// After `decoupled` failed: the composite search over the arms in conflict (the pairs
    /// without a schedule of their own) before prioritized planning, instead of after it.
    pub composite_first: bool,
    /// Shortcut tries (0: no shortcutting).
    pub shortcut_iterations: u64,
    /// Factors (0, 1] on the velocity and acceleration limits of the final timing.
    pub velocity_scaling: f64,
    pub acceleration_scaling: f64,
}

impl Default for MultiArmSettings {
    fn default() -> Self {
        MultiArmSettings {
            methods: Methods::default(),
            rrt: RrtConnectSettings::default(),
            // A schedule not found within 100 phase-space iterations is believed absent: the
            // fallbacks are complete, and on the crossing tasks of `manyhands bench multi-arm`
            // the longer search (1500) made the automatic choice 2–3× slower (the failed
            // schedule was most of its time) without solving more.
            phase: PhaseSpaceSettings {
                max_iterations: 100,
                ..PhaseSpaceSettings::default()
            },
            space_time: SpaceTimeSettings::default(),
            subset_iterations: 5000,
            composite_first: false,
            shortcut_iterations: 200,
            velocity_scaling: 1.0,
            acceleration_scaling: 1.0,
        }
    }
}

fn stopped(term: &Termination) -> Option<PlanError> {
    term.reason()
        .filter(|r| *r != StopReason::IterationLimit)
        .map(|r| PlanError::stopped(r, PlanStats::default()))
}

/// Plans the arms of `p` (module documentation). `term` bounds everything; all randomness
/// comes from `seed`.
pub fn plan_multi_arm(
    p: &MultiArmProblem,
    settings: &MultiArmSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<MultiArmPlan, PlanError> {
    let t0 = Instant::now();
    let n = p.arms.len();
    let mut cell = Cell::new(p);
    let (start, goal) = (p.start(), p.goal());
    if let Some(c) = cell.contact(&start) {
        return Err(PlanError::InvalidStart {
            reason: format!("the arms' start configurations collide ({c})"),
        });
    }
    if let Some(c) = cell.contact(&goal) {
        return Err(PlanError::InvalidGoal {
            count: 1,
            reason: format!("the arms' goal configurations collide ({c})"),
        });
    }
    let vars = p.vars();
    let arm_ranges: Vec<_> = (0..n).map(|k| p.arm_range(k)).collect();
    let limits = world_limits(&p.world)
        .select(&vars)
        .scaled(settings.velocity_scaling, settings.acceleration_scaling)
        .map_err(|e| PlanError::InvalidInput(e.to_string()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut attempts = Vec::new();
    let mut segments = 0u64;
    let mut found: Option<(MultiArmMethod, Vec<Vec<f64>>)> = None;
    let (mut schedule_method, mut order, mut composite_arms, mut conflicts) =
        (None, Vec::new(), Vec::new(), Vec::new());
    let mut alone: Option<Vec<Vec<Vec<f64>>>> = None;
    // The failure of the last method tried (returned when none succeeds).
    let mut last_error: Option<PlanError> = None;

    // (a) decoupled.
    if settings.methods.decoupled {
        let ta = Instant::now();
        let note = match decoupled::plan_alone(p, &settings.rrt, term, seed) {
            Err(e) => {
                if let Some(s) = stopped(term) {
                    return Err(s);
                }
                let note = e.to_string();
                last_error = Some(e.in_phase("decoupled"));
                note
            }
            Ok(paths) => {
                let all: Vec<usize> = (0..n).collect();
                let r = decoupled::schedule(p, &paths, &all, &settings.phase, term, seed);
                alone = Some(paths);
                match r {
                    Ok(s) => {
                        schedule_method = Some(s.method);
                        found = Some((MultiArmMethod::Decoupled, decoupled::schedule_path(p, &s)));
                        format!("schedule {:?}", s.method)
                    }
                    Err(e) => {
                        if let Some(s) = stopped(term) {
                            return Err(s);
                        }
                        let note = format!("no schedule: {e}");
                        last_error = Some(e.in_phase("decoupled"));
                        note
                    }
                }
            }
        };
        attempts.push(Attempt {
            method: MultiArmMethod::Decoupled,
            solved: found.is_some(),
            time: ta.elapsed(),
            note,
        });
    }

    // The composite searches; `conflicts` are known once `decoupled` failed to schedule.
    let mut composite_all_tried = false;
    let mut composite_step = |found: &mut Option<(MultiArmMethod, Vec<Vec<f64>>)>,
                              conflicts: &mut Vec<(usize, usize)>,
                              order: &mut Vec<usize>,
                              composite_arms: &mut Vec<usize>,
                              attempts: &mut Vec<Attempt>,
                              last_error: &mut Option<PlanError>,
                              segments: &mut u64,
                              rng: &mut ChaCha8Rng,
                              term: &mut Termination|
     -> Result<(), PlanError> {
        if found.is_some() || !settings.methods.composite || composite_all_tried {
            return Ok(());
        }
        // The arms in conflict: the pairs whose paths alone have no schedule between the two
        // of them. With two arms the failed schedule of `decoupled` was that pair's already.
        // Their time counts in the first composite attempt.
        let mut ta = Instant::now();
        if let (Some(paths), true) = (&alone, conflicts.is_empty()) {
            *conflicts = if n == 2 {
                vec![(0, 1)]
            } else {
                decoupled::conflicts(p, paths, &settings.phase, term, seed)
            };
        }
        let mut conflicted: Vec<usize> = conflicts.iter().flat_map(|&(a, b)| [a, b]).collect();
        conflicted.sort_unstable();
        conflicted.dedup();
        if !conflicted.is_empty() && conflicted.len() < n {
            let r = composite::composite_subset(
                p,
                &conflicted,
                &settings.rrt,
                &settings.space_time,
                settings.subset_iterations,
                term,
                rng,
                seed,
                segments,
            );
            if let Some(motions) = r {
                *found = Some((
                    MultiArmMethod::Composite,
                    timed::merge(&vars, &start, &motions),
                ));
                *order = conflicted.clone();
                order.extend((0..n).filter(|k| !conflicted.contains(k)));
                *composite_arms = conflicted.clone();
            } else if let Some(s) = stopped(term) {
                return Err(s);
            }
            attempts.push(Attempt {
                method: MultiArmMethod::Composite,
                solved: found.is_some(),
                time: ta.elapsed(),
                note: format!(
                    "{} of {n} arms (those in conflict) in a composite search of at most {} \
                     iterations, the others around them in space-time",
                    conflicted.len(),
                    settings.subset_iterations
                ),
            });
            if found.is_some() {
                return Ok(());
            }
            ta = Instant::now();
        }
        // Over all arms: the complete search, with the rest of the time.
        composite_all_tried = true;
        let note = match composite::composite_all(p, &settings.rrt, term, seed, segments) {
            Ok(m) => {
                *found = Some((MultiArmMethod::Composite, timed::merge(&vars, &start, &[m])));
                *order = (0..n).collect();
                *composite_arms = (0..n).collect();
                format!("{n} arms in the composite search")
            }
            Err(e) => {
                if let Some(s) = stopped(term) {
                    return Err(s);
                }
                let note = e.to_string();
                *last_error = Some(e.in_phase("composite"));
                note
            }
        };
        attempts.push(Attempt {
            method: MultiArmMethod::Composite,
            solved: found.is_some(),
            time: ta.elapsed(),
            note,
        });
        Ok(())
    };
    // Composite before prioritized when so chosen and the arms in conflict can be known.
    if settings.composite_first && alone.is_some() {
        composite_step(
            &mut found,
            &mut conflicts,
            &mut order,
            &mut composite_arms,
            &mut attempts,
            &mut last_error,
            &mut segments,
            &mut rng,
            term,
        )?;
    }

    // (b) prioritized in space-time.
    if found.is_none() && settings.methods.prioritized {
        let ta = Instant::now();
        let initial: Vec<usize> = (0..n).collect();
        let mut tried = Vec::new();
        let r = prioritized::prioritized(
            p,
            &initial,
            &settings.space_time,
            term,
            &mut rng,
            &mut segments,
            &mut tried,
        );
        let solved = r.is_some();
        if let Some((o, motions)) = r {
            found = Some((
                MultiArmMethod::Prioritized,
                timed::merge(&vars, &start, &motions),
            ));
            order = o;
        } else if let Some(s) = stopped(term) {
            return Err(s);
        } else {
            last_error = Some(
                PlanError::IterationLimit {
                    stats: Box::new(PlanStats {
                        time: ta.elapsed(),
                        segments_checked: segments,
                        ..PlanStats::default()
                    }),
                }
                .in_phase(format!(
                    "prioritized ({} priority orders, {} space-time iterations per arm)",
                    tried.len(),
                    settings.space_time.iterations
                )),
            );
        }
        attempts.push(Attempt {
            method: MultiArmMethod::Prioritized,
            solved,
            time: ta.elapsed(),
            note: format!("{} priority orders tried", tried.len()),
        });
    }

    // (c) composite: over the arms in conflict, then over every arm (the complete fallback).
    composite_step(
        &mut found,
        &mut conflicts,
        &mut order,
        &mut composite_arms,
        &mut attempts,
        &mut last_error,
        &mut segments,
        &mut rng,
        term,
    )?;

    let Some((method, raw)) = found else {
        return Err(match (stopped(term), last_error) {
            (Some(s), _) => s,
            (None, Some(e)) => e,
            (None, None) => PlanError::InvalidInput("no method enabled".into()),
        });
    };
    // The raw plan, certified with all arms moving.
    let unproven = |cell: &mut Cell, path: &[Vec<f64>]| -> Result<(), PlanError> {
        match cell.first_unproven(path) {
            None => Ok(()),
            Some(segment) => Err(PlanError::PathInvalid {
                segment,
                stats: Box::new(PlanStats {
                    time: t0.elapsed(),
                    ..PlanStats::default()
                }),
            }),
        }
    };
    let raw = if raw.len() == 1 {
        vec![raw[0].clone(), raw[0].clone()]
    } else {
        raw
    };
    unproven(&mut cell, &raw)?;
    let planning_time = t0.elapsed();
    let vertices_raw = raw.len();
    let ts = Instant::now();
    let (path, rep) = shortcut::shortcut(
        &mut cell,
        raw,
        &arm_ranges,
        &limits,
        settings.shortcut_iterations,
        term,
        &mut rng,
    );
    unproven(&mut cell, &path)?;
    let shortcut_time = ts.elapsed();
    let timed = time_polyline(&path, &limits, &[])
        .map_err(|e| PlanError::InvalidInput(format!("timing: {e}")))?;
    let makespan = timed.duration;
    Ok(MultiArmPlan {
        method,
        schedule_method,
        order,
        composite_arms,
        conflicts,
        vars,
        arm_ranges,
        stats: MultiArmStats {
            time: t0.elapsed(),
            planning_time,
            shortcut_time,
            attempts,
            segments_certified: segments + cell.segments,
            vertices_raw,
            vertices: path.len(),
            shortcuts_tried: rep.tried,
            shortcuts_composite: rep.composite_kept,
            shortcuts_per_arm: rep.per_arm_kept,
        },
        path,
        timed,
        makespan_before: rep.makespan_before,
        makespan,
    })
}
