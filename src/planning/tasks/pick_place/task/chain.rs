//! The motion chain of one attempt of the pick-and-place task (module docs of [`super`]): its
//! worlds, the hand motions on the object with their certificates, the four queries, and the
//! re-certification of the whole plan.

use super::*;

/// The motion chain of one attempt (module docs).
pub(super) struct Chain<'a> {
    pub(super) p: &'a PickPlaceProblem,
    pub(super) off: &'a PickPlaceOffline,
    pub(super) settings: &'a PickPlaceSettings,
    /// The approachable grasps of both lists ([`approachable`]) and their indices in the
    /// offline lists.
    pub(super) pick_list: &'a GraspList,
    pub(super) place_list: &'a GraspList,
    pub(super) pick_index: &'a [usize],
    pub(super) place_index: &'a [usize],
    /// Each approachable grasp's certified closing motions ([`closable`]).
    pub(super) pick_motions: &'a [Vec<Vec<Vec<f64>>>],
    pub(super) place_motions: &'a [Vec<Vec<Vec<f64>>>],
    pub(super) plan: TaskPlan,
    /// The world of each phase of `plan` (an index into `worlds`).
    pub(super) phase_world: Vec<usize>,
    /// The object certificate of each phase that closes or opens a hand on the object.
    pub(super) phase_fingers: Vec<Option<ObjectCertificate<'a>>>,
    pub(super) queries: Vec<QueryRecord>,
    /// What the roadmap learnt so far (module docs of [`crate::planning::planners::roadmap_query`]).
    pub(super) learned: LearnedGraph,
    /// The grasp (0: pick, 1: place; index into its approachable list) none of whose closing
    /// motions is free in the scene, when that ended the chain.
    pub(super) refused: Option<(usize, usize)>,
    pub(super) seed: u64,
    pub(super) attempt: usize,
    pub(super) t0: Instant,
    /// The worlds of the chain (object resting at q_o^i, held by one hand or both, resting at
    /// q_o^f) and their checkers, each built once per attempt when first needed.
    pub(super) worlds: Vec<CollisionWorld>,
    pub(super) fast: Vec<Option<FastChecker>>,
    pub(super) exact: Vec<Option<ExactChecker>>,
}

/// Certified closing motions kept per grasp ([`super::super::fingers::closing_motions`]): the chain
/// takes the first whose pre-shape is free in the scene.
pub(super) const CLOSING_CANDIDATES: usize = 12;

/// The worlds of [`Chain::worlds`].
const W_INITIAL: usize = 0;
const W_PICK_HAND: usize = 1;
const W_BOTH_HANDS: usize = 2;
const W_PLACE_HAND: usize = 3;
const W_FINAL: usize = 4;
/// The object resting at q_o^i, the pick hand's links not checked against it (the pick
/// approach, proven against the object by its [`ApproachCertificate`]).
const W_PICK_APPROACH: usize = 5;
/// The object held by the place hand at q_o^e, the pick hand's links not checked against it
/// (the pick hand's departure after it opened, proven by its [`ApproachCertificate`]).
const W_PICK_DEPART: usize = 6;

impl<'a> Chain<'a> {
    /// The fast checker of world `w` (built on first use: one per world and attempt, so a hand
    /// motion certified while its pre-shape was chosen is not proven again).
    fn fast(&mut self, w: usize) -> &mut FastChecker {
        let world = &self.worlds[w];
        self.fast[w].get_or_insert_with(|| FastChecker::new(world))
    }

    fn append(&mut self, name: &str, planner: &str, path: Vec<Vec<f64>>, w: usize) {
        let first = self.plan.waypoints.len().saturating_sub(1);
        let skip = usize::from(!self.plan.waypoints.is_empty());
        let vertices = path.len();
        self.plan.waypoints.extend(path.into_iter().skip(skip));
        self.plan.phases.push(TaskPhase {
            name: name.into(),
            planner: planner.into(),
            first,
            last: self.plan.waypoints.len() - 1,
            stats: PlanStats {
                vertices_raw: vertices,
                vertices_simplified: vertices,
                ..PlanStats::default()
            },
            world: self.worlds[w].clone(),
        });
        self.phase_world.push(w);
        self.phase_fingers.push(None);
    }

    fn event(&mut self, kind: EventKind, ah: &ArmHand, grasp: String) {
        self.plan.events.push(TaskEvent {
            waypoint: self.plan.waypoints.len() - 1,
            kind,
            robot: self.off.world.robots[0].name.clone(),
            end_effector: ah.hand.group.clone(),
            object: self.p.object_name.clone(),
            grasp,
        });
    }

    fn last(&self) -> Vec<f64> {
        self.plan.waypoints.last().cloned().unwrap_or_default()
    }

    /// A straight finger motion from the last waypoint to `q`, certified in world `w` (the
    /// hand away from the object or not allowed to touch it there).
    fn fingers(&mut self, name: &str, q: Vec<f64>, w: usize) -> Result<(), PickPlaceTaskError> {
        let a = self.last();
        if a == q {
            return Ok(());
        }
        if !self.fast(w).motion_certified(&a, &q) {
            return Err(PickPlaceTaskError::Hand(format!(
                "{name}: the hand motion is not certified free"
            )));
        }
        self.append(name, "fingers", vec![a, q], w);
        Ok(())
    }

    /// A hand closing on the object or opening from it ([`super::super::fingers`]): `path` from the
    /// last waypoint, certified in world `w` (where the hand may touch the object) and
    /// against the object by `cert`.
    fn on_object(
        &mut self,
        name: &str,
        path: Vec<Vec<f64>>,
        w: usize,
        cert: ObjectCertificate<'a>,
    ) -> Result<(), PickPlaceTaskError> {
        if path.first() != Some(&self.last()) {
            return Err(PickPlaceTaskError::Hand(format!(
                "{name}: the hand motion does not start where the plan is"
            )));
        }
        for s in path.windows(2) {
            if !self.fast(w).motion_certified(&s[0], &s[1]) {
                return Err(PickPlaceTaskError::Hand(format!(
                    "{name}: the hand motion is not certified free"
                )));
            }
            if let v @ (FingerVerdict::Collides { .. }
            | FingerVerdict::Unproven { .. }
            | FingerVerdict::NotFingers) = cert.certify(&s[0], &s[1])
            {
                return Err(PickPlaceTaskError::Hand(format!(
                    "{name}: the hand motion is not certified free of the object ({v:?})"
                )));
            }
        }
        self.append(name, "fingers", path, w);
        if let Some(f) = self.phase_fingers.last_mut() {
            *f = Some(cert);
        }
        Ok(())
    }

    /// The closing motion of `ah` onto the grasp whose candidate motions are `motions`, the
    /// arm at `q` (the grasp state): world configurations `[pre-shape, (approach,) q]` of the
    /// first candidate whose pre-shape is free in world `state` (exact and fast checker) and
    /// whose segments are certified in world `motion` (the object is proven by the phase's
    /// [`super::super::fingers::FingerCertificate`]).
    #[allow(clippy::too_many_arguments)]
    fn closing(
        &mut self,
        ah: &ArmHand,
        (side, grasp): (usize, usize),
        motions: &[Vec<Vec<f64>>],
        q: &[f64],
        (state, motion): (usize, usize),
        what: &str,
    ) -> Result<Vec<Vec<f64>>, PickPlaceTaskError> {
        let (worlds, fast, exact) = (&self.worlds, &mut self.fast, &mut self.exact);
        let found = first_free(ah, q, motions, &mut |t| match t {
            Test::Free(x) => {
                // Fast (conservative, cheap) first, as `super::room` does.
                let w = &worlds[state];
                fast[state]
                    .get_or_insert_with(|| FastChecker::new(w))
                    .is_free(x)
                    && exact[state]
                        .get_or_insert_with(|| ExactChecker::new(w))
                        .is_free(x)
            }
            Test::Motion(a, b) => {
                let w = &worlds[motion];
                fast[motion]
                    .get_or_insert_with(|| FastChecker::new(w))
                    .motion_certified(a, b)
            }
        });
        if let Some(path) = found {
            return Ok(path);
        }
        self.refused = Some((side, grasp));
        Err(PickPlaceTaskError::Hand(format!(
            "{what}: none of the {} certified closing motions of '{}' is free there",
            motions.len(),
            ah.hand.group
        )))
    }

    /// The object certificate of `ah` on grasp `g` of `list` with the arm at `q`.
    fn certificate(
        &self,
        ah: &'a ArmHand,
        list: &GraspList,
        g: &SingleGrasp,
        q: &[f64],
    ) -> ObjectCertificate<'a> {
        let off: &'a PickPlaceOffline = self.off;
        ObjectCertificate::Fingers(super::super::fingers::FingerCertificate::new(
            ah,
            &off.object,
            g,
            q,
            list.params.contact_tolerance,
        ))
    }

    /// The approach of `ah`'s pre-shaped hand to `pre` ([`super::super::approach`]): the first
    /// approach configuration (directions best first, distances farthest first) free in world
    /// `state`, whose straight motion to `pre` is certified in world `motion` (the hand–object
    /// pairs left out) and against the object at `object` (world pose) by its certificate.
    fn approach(
        &mut self,
        ah: &'a ArmHand,
        pre: &[f64],
        object: &Pose,
        (state, motion): (usize, usize),
    ) -> Option<(Vec<f64>, ObjectCertificate<'a>)> {
        let off: &'a PickPlaceOffline = self.off;
        let p = self.p;
        let in_root = p.base.inverse() * object;
        let cert = ApproachCertificate::new(ah, &off.object, &in_root);
        let centre = in_root * nalgebra::Point3::from(p.object_centre);
        for dir in approach_directions(p, ah, pre, &centre.coords) {
            for &s in &APPROACH_DISTANCES {
                let Some(far) = approach_configuration(p, ah, pre, &dir, s) else {
                    continue;
                };
                if self.fast(state).is_free(&far)
                    && cert.certify(&far, pre) == FingerVerdict::Certified
                    && self.fast(motion).motion_certified(&far, pre)
                {
                    return Some((far, ObjectCertificate::Approach(cert)));
                }
            }
        }
        None
    }

    /// Query `name` from the last waypoint to `goal` in world `w`, appended.
    fn query(
        &mut self,
        name: &'static str,
        goal: Vec<f64>,
        w: usize,
        term: &mut Termination,
        progress: &mut dyn FnMut(TaskProgress),
    ) -> Result<(), PickPlaceTaskError> {
        progress(TaskProgress {
            phase: match name {
                "grasp" => "query_grasp",
                "carry" => "query_carry",
                "place" => "query_place",
                _ => "query_rest",
            },
            attempt: self.attempt,
            elapsed_ms: ms(self.t0),
        });
        let start = self.last();
        let seed = self.seed.wrapping_add(self.queries.len() as u64 + 1);
        let sg = &self.off.graph;
        let world = &self.worlds[w];
        let tagged = |error: PlanError| PickPlaceTaskError::Phase {
            phase: name.into(),
            error,
        };
        let t = Instant::now();
        let (path, rec) = match self.settings.planner {
            MotionPlanner::Roadmap => {
                let r = query_learning(
                    sg,
                    Some(&mut self.learned),
                    world,
                    &start,
                    &goal,
                    &self.settings.query,
                    term,
                    seed,
                )
                .map_err(tagged)?;
                let s = r.stats;
                let rec = QueryRecord {
                    name: name.into(),
                    planner: MotionPlanner::Roadmap,
                    nodes: s.first_path_nodes,
                    planning_ms: s.total_ms - s.validation_ms,
                    validated: s.nodes_validated + s.edges_validated,
                    invalid: s.invalid_nodes + s.invalid_edges,
                    validation_ms: s.validation_ms,
                    rrt_repairs: s.rrt_repairs,
                    learned_nodes: s.learned_nodes,
                    learned_added: s.learned_added,
                    direct: s.direct,
                    vertices: s.vertices,
                    total_ms: s.total_ms,
                    connect_ms: s.connect_ms,
                    search_ms: s.search_ms,
                    rrt_ms: s.rrt_ms,
                    shortcut_ms: s.shortcut_ms,
                };
                (r.world_path, rec)
            }
            MotionPlanner::RrtConnect => {
                let space = sg.space(world, start.clone()).map_err(tagged)?;
                let mut rrt = RrtConnect::with_checker(
                    space.clone(),
                    world,
                    space_checker(world, &space),
                    self.settings.query.rrt,
                )
                .map_err(tagged)?;
                let r = rrt
                    .plan(
                        &space.from_world(&start),
                        &[space.from_world(&goal)],
                        term,
                        seed,
                    )
                    .map_err(tagged)?;
                let total = ms(t);
                let rec = QueryRecord {
                    name: name.into(),
                    planner: MotionPlanner::RrtConnect,
                    nodes: r.stats.start_tree_size + r.stats.goal_tree_size,
                    planning_ms: total,
                    vertices: r.path.len(),
                    total_ms: total,
                    ..QueryRecord::default()
                };
                (space.path_to_world(&r.path), rec)
            }
        };
        let planner = match self.settings.planner {
            MotionPlanner::Roadmap => "super_graph",
            MotionPlanner::RrtConnect => "rrt_connect",
        };
        self.append(name, planner, path, w);
        if let Some(ph) = self.plan.phases.last_mut() {
            ph.stats.time = Duration::from_secs_f64(rec.total_ms.max(0.0) / 1e3);
        }
        self.queries.push(rec);
        Ok(())
    }
}

/// The motion chain for key configurations `keys` (module docs).
pub(super) fn chain<'a>(
    c: &mut Chain<'a>,
    keys: &KeyConfigurations,
    term: &mut Termination,
    progress: &mut dyn FnMut(TaskProgress),
) -> Result<(), PickPlaceTaskError> {
    let (p, off) = (c.p, c.off);
    let (pick, place) = (&p.pick, &p.place);
    let a = &c.pick_list.grasps[keys.double.pick];
    let b = &c.place_list.grasps[keys.double.place];
    let (name_a, name_b) = (
        format!("{}#{}", pick.hand.group, c.pick_index[keys.double.pick]),
        format!("{}#{}", place.hand.group, c.place_index[keys.double.place]),
    );
    let plan_err = |e: PlanError| PickPlaceTaskError::Phase {
        phase: "attach".into(),
        error: e,
    };
    let w_i = &off.world;
    let rel_a = a.palm_pose().inverse();
    let rel_b = b.palm_pose().inverse();
    let mut both = pick.links.clone();
    both.extend(place.links.iter().copied());
    let qg = keys.grasp.q.clone();
    let qe = keys.exchange.clone();
    let h_a = attach_at_link(
        w_i,
        &p.object_name,
        0,
        pick.hand.palm,
        &rel_a,
        &qg,
        pick.links.clone(),
    )
    .map_err(plan_err)?;
    let h_ab = attach_at_link(w_i, &p.object_name, 0, pick.hand.palm, &rel_a, &qe, both)
        .map_err(plan_err)?;
    let h_b = attach_at_link(
        w_i,
        &p.object_name,
        0,
        place.hand.palm,
        &rel_b,
        &qe,
        place.links.clone(),
    )
    .map_err(plan_err)?;
    let mut w_f = w_i.clone();
    if let Some(s) = w_f.statics.iter_mut().find(|s| s.name == p.object_name) {
        s.pose = p.final_pose;
    }
    let mut w_ia = w_i.clone();
    if let Some(si) = w_ia.statics.iter().position(|s| s.name == p.object_name) {
        for &l in &pick.links {
            w_ia.allow(BodyId::Link { robot: 0, link: l }, BodyId::Static(si));
        }
    }
    let mut h_bd = h_b.clone();
    if let Some(ai) = h_bd.attached.iter().position(|a| a.name == p.object_name) {
        for &l in &pick.links {
            h_bd.allow(BodyId::Link { robot: 0, link: l }, BodyId::Attached(ai));
        }
    }
    c.worlds = vec![w_i.clone(), h_a, h_ab, h_b, w_f, w_ia, h_bd];
    c.fast = (0..7).map(|_| None).collect();
    c.exact = (0..7).map(|_| None).collect();
    let (w_i, h_a, h_ab, h_b, w_f) = (W_INITIAL, W_PICK_HAND, W_BOTH_HANDS, W_PLACE_HAND, W_FINAL);

    let (motions_a, motions_b) = (
        c.pick_motions[keys.double.pick].as_slice(),
        c.place_motions[keys.double.place].as_slice(),
    );
    let (list_a, list_b) = (c.pick_list, c.place_list);

    // The four hand motions on the object first (cheap; a grasp none of whose closing motions
    // is free in the scene ends the chain before any query).
    let (ga, gb) = ((0, keys.double.pick), (1, keys.double.place));
    let close_a = c.closing(pick, ga, motions_a, &qg, (w_i, h_a), "grasp")?;
    let close_b = c.closing(place, gb, motions_b, &qe, (h_a, h_ab), "exchange")?;
    let mut open_a = c.closing(pick, ga, motions_a, &qe, (h_b, h_ab), "exchange")?;
    open_a.reverse();
    let qe_free = open_a.last().cloned().unwrap_or_else(|| qe.clone());
    let qp = with_fingers(pick, &keys.place.q, &fingers_of(pick, &qe_free));
    let mut open_b = c.closing(place, gb, motions_b, &qp, (w_f, h_b), "place")?;
    open_b.reverse();

    // Grasp: pre-shape the pick hand at rest, reach q_r^g pre-shaped, close.
    c.plan.waypoints = vec![p.rest.clone()];
    c.fingers(
        "pick_preshape",
        with_fingers(pick, &p.rest, &fingers_of(pick, &close_a[0])),
        w_i,
    )?;
    // The query ends at the approach configuration when one is certified (`super::approach`).
    let approach = c.approach(pick, &close_a[0], &p.initial, (w_i, W_PICK_APPROACH));
    match approach {
        Some((far, cert)) => {
            c.query("grasp", far.clone(), w_i, term, progress)?;
            let path = vec![far, close_a[0].clone()];
            c.on_object("pick_approach", path, W_PICK_APPROACH, cert)?;
        }
        None => c.query("grasp", close_a[0].clone(), w_i, term, progress)?,
    }
    let cert = c.certificate(pick, list_a, a, &qg);
    c.on_object("pick_close", close_a, h_a, cert)?;
    c.event(EventKind::Grasp, pick, name_a.clone());

    // Carry: pre-shape the place hand, bring the object to q_o^e, close the place hand.
    c.fingers(
        "place_preshape",
        with_fingers(place, &qg, &fingers_of(place, &close_b[0])),
        h_a,
    )?;
    c.query("carry", close_b[0].clone(), h_a, term, progress)?;
    let cert = c.certificate(place, list_b, b, &qe);
    c.on_object("place_close", close_b, h_ab, cert)?;
    c.event(EventKind::Grasp, place, name_b.clone());
    c.event(EventKind::Release, pick, name_a);

    // Place: open the pick hand (its closing motion reversed), bring the object to q_o^f.
    let cert = c.certificate(pick, list_a, a, &qe);
    c.on_object("pick_open", open_a, h_ab, cert)?;
    // The pick hand backs off from the object the place hand now holds (the reverse of an
    // approach, `super::approach`), so the place query starts clear of it.
    let opened = c.last();
    let held = link_pose(&p.robot, &opened, place.hand.palm) * b.palm_pose().inverse();
    if let Some((far, cert)) = c.approach(pick, &opened, &(p.base * held), (h_b, W_PICK_DEPART)) {
        c.on_object("pick_depart", vec![opened, far], W_PICK_DEPART, cert)?;
    }
    c.query("place", qp.clone(), h_b, term, progress)?;
    c.event(EventKind::Release, place, name_b);

    // Rest: open the place hand, back to q_r^i, fingers to their rest values.
    let qp_open = open_b.last().cloned().unwrap_or_else(|| qp.clone());
    let cert = c.certificate(place, list_b, b, &qp);
    c.on_object("place_open", open_b, h_b, cert)?;
    let mut q_end = p.rest.clone();
    q_end = with_fingers(pick, &q_end, &fingers_of(pick, &qp_open));
    q_end = with_fingers(place, &q_end, &fingers_of(place, &qp_open));
    c.query("rest", q_end, w_f, term, progress)?;
    c.fingers("fingers_rest", p.rest.clone(), w_f)?;
    Ok(())
}

/// Re-certifies every motion of `plan` in its phase's world and every waypoint's limits; the
/// number of segments checked. The phases' worlds are `worlds[phase_world[i]]`, checked with
/// the chain's checker of that world (`checkers`, built where missing) after it forgot the
/// motions it proved ([`FastChecker::forget_proven`]): every motion is proven again. A phase
/// that closes or opens a hand on the object is also proven against the object by its
/// certificate (`fingers[i]`, [`super::super::fingers`]).
pub(super) fn certify(
    p: &PickPlaceProblem,
    plan: &TaskPlan,
    worlds: &[CollisionWorld],
    phase_world: &[usize],
    fingers: &[Option<ObjectCertificate>],
    checkers: &mut [Option<FastChecker>],
) -> Result<usize, PickPlaceTaskError> {
    if let Some(k) = plan.waypoints.iter().position(|q| !within_limits(p, q)) {
        return Err(PickPlaceTaskError::NotCertified {
            phase: "plan".into(),
            segment: k,
            reason: "waypoint outside the joint limits".into(),
        });
    }
    let mut n = 0;
    for c in checkers.iter_mut().flatten() {
        c.forget_proven();
    }
    for (i, ph) in plan.phases.iter().enumerate() {
        let world = phase_world
            .get(i)
            .and_then(|&w| Some((worlds.get(w)?, checkers.get_mut(w)?)));
        let fast = match world {
            Some((world, c)) => c.get_or_insert_with(|| FastChecker::new(world)),
            None => {
                return Err(PickPlaceTaskError::NotCertified {
                    phase: ph.name.clone(),
                    segment: ph.first,
                    reason: "the phase has no world".into(),
                })
            }
        };
        for k in ph.first..ph.last {
            n += 1;
            let (a, b) = (&plan.waypoints[k], &plan.waypoints[k + 1]);
            if !fast.motion_certified(a, b) {
                return Err(PickPlaceTaskError::NotCertified {
                    phase: ph.name.clone(),
                    segment: k,
                    reason: "the motion is not certified free".into(),
                });
            }
            if let Some(Some(cert)) = fingers.get(i) {
                let v = cert.certify(a, b);
                if v != FingerVerdict::Certified {
                    return Err(PickPlaceTaskError::NotCertified {
                        phase: ph.name.clone(),
                        segment: k,
                        reason: format!(
                            "the hand motion is not certified free of the object ({v:?})"
                        ),
                    });
                }
            }
        }
    }
    Ok(n)
}
