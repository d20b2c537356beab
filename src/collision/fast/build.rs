//! Building the [`FastChecker`]: the primitives of every body, the pair list without the pairs
//! no configuration within the joint limits brings together (`pair_can_touch`), the grouping
//! of pairs, and, for a checker of some variables only, the pairs whose relative pose is
//! constant moved out of the per-check list. Split from `fast.rs` by concept; code moved
//! unchanged.

use super::*;

impl FastChecker {
    pub(super) fn build(
        world: &CollisionWorld,
        settings: FastModelSettings,
        freeze: Option<(&[usize], &[f64])>,
    ) -> FastChecker {
        let freeze = freeze.filter(|(_, q0)| q0.len() == world.dof());
        // Reduced FK: links behind fixed (or frozen) joints ride on the last moving link.
        let fk_models: Vec<FkModel> = world
            .robots
            .iter()
            .map(|p| match freeze {
                Some((active, q0)) => {
                    let dof = p.robot.dof();
                    let mask: Vec<bool> =
                        (0..dof).map(|v| active.contains(&(p.offset + v))).collect();
                    FkModel::frozen(&p.robot, &mask, &q0[p.offset..p.offset + dof])
                }
                None => FkModel::reduced(&p.robot),
            })
            .collect();
        let mount_of = |robot: usize, link: usize, rel: Option<Frame>| -> (Mount, Option<Frame>) {
            let (rep, off) = fk_models[robot].mount(link);
            let rel = match (off, rel) {
                (Some(o), Some(r)) => Some(o.mul(&r)),
                (Some(o), None) => Some(o),
                (None, r) => r,
            };
            (Mount { robot, link: rep }, rel)
        };
        let mut moving = Vec::new();
        // Body → index tables (plain vectors: hashing showed in per-problem setup).
        let mut link_index: Vec<Vec<Option<usize>>> = world
            .robots
            .iter()
            .map(|p| vec![None; p.robot.links.len()])
            .collect();
        let mut attached_index: Vec<Option<usize>> = vec![None; world.attached.len()];
        let mut start = 0;
        let mut gstart = 0;
        let mut overapprox: f64 = 0.0;
        let mut push_body = |id: BodyId,
                             mount: Mount,
                             rel: Option<Frame>,
                             shapes: &[crate::geometry::Geometry],
                             coarse: bool,
                             moving: &mut Vec<MovingBody>| {
            // Primitives in the mount link's frame (the body's offset folded in), so a check
            // needs only the link frames.
            let mut local: Vec<Prim> = Vec::with_capacity(shapes.len());
            let mut covers = Vec::new();
            for g in shapes {
                let first = local.len();
                if Prim::from_shape(&g.origin, &g.shape, settings.padding, coarse, &mut local) {
                    covers.push(first..local.len());
                }
            }
            if let Some(f) = &rel {
                for p in &mut local {
                    *p = p.transformed(&f.rot, &f.t);
                }
            }
            let groups = groups::group_moving(&mut local, &covers);
            let (bc, br) = bounding_of(&local);
            match id {
                BodyId::Link { robot, link } => link_index[robot][link] = Some(moving.len()),
                BodyId::Attached(a) => attached_index[a] = Some(moving.len()),
                BodyId::Static(_) => {}
            }
            let (n, ng) = (local.len(), groups.len());
            moving.push(MovingBody {
                id,
                mount,
                local,
                bc,
                br,
                start,
                groups,
                gstart,
            });
            start += n;
            gstart += ng;
        };
        for (r, p) in world.robots.iter().enumerate() {
            for (l, link) in p.robot.links.iter().enumerate() {
                if !link.collision.is_empty() {
                    let (mount, rel) = mount_of(r, l, None);
                    push_body(
                        BodyId::Link { robot: r, link: l },
                        mount,
                        rel,
                        &link.collision,
                        true,
                        &mut moving,
                    );
                }
            }
        }
        for (a, at) in world.attached.iter().enumerate() {
            if !at.shapes.is_empty() {
                let (mount, rel) = mount_of(at.robot, at.link, Some(Frame::from_pose(&at.rel)));
                // A held object keeps its fine cover: a hand comes to within millimetres of it
                // (the other hand at a hand-over), which the coarse cover would refuse.
                push_body(
                    BodyId::Attached(a),
                    mount,
                    rel,
                    &at.shapes,
                    false,
                    &mut moving,
                );
            }
        }
        let mut statics = Vec::new();
        let mut static_index: Vec<Option<usize>> = vec![None; world.statics.len()];
        for (s, st) in world.statics.iter().enumerate() {
            if st.shapes.is_empty() {
                continue;
            }
            let mut plain = Vec::with_capacity(st.shapes.len());
            for g in &st.shapes {
                Prim::from_shape(&(st.pose * g.origin), &g.shape, 0.0, false, &mut plain);
            }
            let mut prims: Vec<(Prim, Vector3<f64>, Vector3<f64>)> = plain
                .into_iter()
                .map(|p| {
                    let (lo, hi) = aabb(&p);
                    (p, lo, hi)
                })
                .collect();
            let groups = groups::group_static(&mut prims);
            let lo = prims
                .iter()
                .fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(&p.1));
            let hi = prims
                .iter()
                .fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(&p.2));
            static_index[s] = Some(statics.len());
            statics.push(StaticBodyModel {
                id: BodyId::Static(s),
                prims,
                groups,
                lo,
                hi,
            });
        }
        // Meshes are over-approximated by their cover (a solid's boxes: at most a cell diagonal,
        // on both bodies of a pair; the coarse cover on robot links) or the box around their
        // vertices (unbounded against the exact checker's hull).
        let link_shapes = world
            .robots
            .iter()
            .flat_map(|p| p.robot.links.iter().flat_map(|l| l.collision.iter()));
        let fine_shapes = world
            .attached
            .iter()
            .flat_map(|a| a.shapes.iter())
            .chain(world.statics.iter().flat_map(|s| s.shapes.iter()));
        let shapes = link_shapes
            .map(|g| (g, true))
            .chain(fine_shapes.map(|g| (g, false)));
        for (g, moving) in shapes {
            let o = match &g.shape {
                Shape::Mesh(m) if moving => 2.0 * (m.moving_cover().1 + EPS),
                Shape::Mesh(m) => 2.0 * (m.cover_protrusion() + EPS),
                _ => 2.0 * EPS,
            };
            overapprox = overapprox.max(o);
        }
        overapprox += settings.padding;
        let moving_of = |id: BodyId| match id {
            BodyId::Link { robot, link } => link_index[robot][link],
            BodyId::Attached(a) => attached_index[a],
            BodyId::Static(_) => None,
        };
        let static_of = |id: BodyId| match id {
            BodyId::Static(s) => static_index[s],
            _ => None,
        };
        let mut pairs = Vec::new();
        for (a, b) in world.pairs() {
            match (moving_of(a), moving_of(b), static_of(b), static_of(a)) {
                (Some(ia), Some(ib), _, _) => pairs.push(Pair {
                    a: ia as u32,
                    b: ib as u32,
                    b_static: false,
                    reach2: (moving[ia].br + moving[ib].br).powi(2),
                }),
                (Some(ia), None, Some(sb), _) => pairs.push(Pair {
                    a: ia as u32,
                    b: sb as u32,
                    b_static: true,
                    reach2: moving[ia].br.powi(2),
                }),
                (None, Some(ib), _, Some(sa)) => pairs.push(Pair {
                    a: ib as u32,
                    b: sa as u32,
                    b_static: true,
                    reach2: moving[ib].br.powi(2),
                }),
                _ => {}
            }
        }
        // Pairs that no configuration within the joint limits brings into contact are dropped.
        let bases: Vec<Frame> = world
            .robots
            .iter()
            .map(|p| Frame::from_pose(&p.base))
            .collect();
        pairs.retain(|p| pair_can_touch(world, &fk_models, &bases, &moving, &statics, p));
        // Pairs against fixed bodies grouped per fixed body (a whole group is skipped when the
        // body's box misses the box around all moving bodies), then moving–moving pairs.
        pairs.sort_by_key(|p| {
            if p.b_static {
                (0, p.b, p.a)
            } else {
                (1, p.a, p.b)
            }
        });
        let (static_groups, self_start) = group_pairs(&pairs);
        let link_poses: Vec<Vec<Frame>> = world
            .robots
            .iter()
            .map(|p: &PlacedRobot| vec![Frame::identity(); p.robot.links.len()])
            .collect();
        let fk = fk_models;
        let nb = moving.len();
        let prim_radius = moving
            .iter()
            .flat_map(|b| b.local.iter().map(|p| p.bounding().1))
            .collect();
        let group_radius: Vec<f64> = moving
            .iter()
            .flat_map(|b| b.groups.iter().map(|g| g.bound.bounding().1))
            .collect();
        let ng = group_radius.len();
        let mut checker = FastChecker {
            world: world.clone(),
            moving,
            statics,
            pairs,
            static_groups,
            self_start,
            moving_lo: Vector3::zeros(),
            moving_hi: Vector3::zeros(),
            fk_last: vec![Vec::new(); world.robots.len()],
            piece_poses: link_poses.clone(),
            piece_last: vec![Vec::new(); world.robots.len()],
            fk,
            bases,
            link_poses,
            body_bc: vec![Vector3::zeros(); nb],
            world_prims: vec![
                Prim::Sphere {
                    c: Vector3::zeros(),
                    r: 0.0
                };
                start
            ],
            prim_radius,
            prims_ready: vec![0; nb],
            prims_frame: vec![
                Frame {
                    rot: nalgebra::Matrix3::repeat(f64::NAN),
                    t: Vector3::repeat(f64::NAN),
                };
                nb
            ],
            world_groups: vec![
                Prim::Sphere {
                    c: Vector3::zeros(),
                    r: 0.0
                };
                ng
            ],
            group_radius,
            group_ready: vec![0; ng],
            unit_pairs: Vec::new(),
            mount_c: Vec::new(),
            dynamic: (0..nb as u32).collect(),
            epoch: 0,
            checks: 0,
            overapprox,
            settings,
            frozen: None,
            sweep: Default::default(),
            skip_inflation: FastChecker::SKIP_INFLATION,
            certify: Some(FastChecker::CERTIFY_INFLATION),
            certify_stats: CertifyStats::default(),
            certify_finest: f64::INFINITY,
            proven: ProvenMotions::default(),
        };
        if let Some((active, q0)) = freeze {
            checker.split_constant_pairs(active, q0);
        }
        checker.sweep = sweep::Sweep::new(&checker);
        checker.mount_c = vec![Vector3::zeros(); checker.sweep.mount_count()];
        checker
    }

    /// Moves the pairs whose relative pose is constant out of the per-check list, after
    /// testing them once at `q0`.
    fn split_constant_pairs(&mut self, active: &[usize], q0: &[f64]) {
        self.prepare(q0);
        // A body on link 0 of its robot (in the frozen FK) does not move at all.
        let still = |b: &MovingBody| b.mount.link == 0;
        let mut constant_hit = None;
        let mut kept = Vec::with_capacity(self.pairs.len());
        for pi in 0..self.pairs.len() {
            let p = self.pairs[pi];
            let a = &self.moving[p.a as usize];
            let constant = if p.b_static {
                still(a)
            } else {
                let b = &self.moving[p.b as usize];
                (still(a) && still(b))
                    || (a.mount.robot == b.mount.robot && a.mount.link == b.mount.link)
            };
            if !constant {
                kept.push(p);
                continue;
            }
            if constant_hit.is_none() && self.pair_hits(pi) {
                constant_hit = Some(p);
            }
        }
        // Bodies that do not move keep their frames and world primitives from here on.
        let mut dynamic = Vec::with_capacity(self.moving.len());
        for i in 0..self.moving.len() {
            if still(&self.moving[i]) {
                self.ensure_prims(i);
                self.make_groups_permanent(i);
                self.prims_ready[i] = PERMANENT;
            } else {
                dynamic.push(i as u32);
            }
        }
        self.dynamic = dynamic;
        self.pairs = kept;
        let (groups, self_start) = group_pairs(&self.pairs);
        self.static_groups = groups;
        self.self_start = self_start;
        let active: Vec<usize> = active.to_vec();
        let fixed = (0..q0.len())
            .filter(|v| !active.contains(v))
            .map(|v| (v, q0[v]))
            .collect();
        self.frozen = Some(Frozen {
            active,
            fixed,
            constant_hit,
        });
    }
}

/// Whether pair `p` may touch in some configuration within the joint limits (a conservative
/// test: false only when it can never touch). Each body's bounding sphere is bounded by a ball
/// fixed in the frame of the two bodies' first common computed ancestor — the world for two
/// robots or a fixed body — ([`FkModel::reach_ball`]); balls that cannot meet prove the pair
/// apart.
fn pair_can_touch(
    world: &CollisionWorld,
    fk: &[FkModel],
    bases: &[Frame],
    moving: &[MovingBody],
    statics: &[StaticBodyModel],
    p: &Pair,
) -> bool {
    let ball = |b: &MovingBody, ancestor: usize| {
        let r = b.mount.robot;
        fk[r].reach_ball(&world.robots[r].robot, b.mount.link, &b.bc, b.br, ancestor)
    };
    // About the robot's root link (link 0, placed at the robot's base pose).
    let in_world = |b: &MovingBody| {
        let (c, r) = ball(b, 0)?;
        Some((bases[b.mount.robot].transform_point(&c), r))
    };
    let a = &moving[p.a as usize];
    if p.b_static {
        let s = &statics[p.b as usize];
        return match in_world(a) {
            Some((c, r)) => dist2_point_aabb(&c, &s.lo, &s.hi) <= r * r,
            None => true,
        };
    }
    let b = &moving[p.b as usize];
    let balls = if a.mount.robot == b.mount.robot {
        let fa = fk[a.mount.robot].ancestors(a.mount.link);
        let fb = fk[b.mount.robot].ancestors(b.mount.link);
        // Both lists end at the root: the first common ancestor is the last element of
        // their common tail (O(depth), not O(depth²), for a chain of hundreds of links).
        let common = fa
            .iter()
            .rev()
            .zip(fb.iter().rev())
            .take_while(|(x, y)| x == y)
            .last()
            .map(|(&c, _)| c);
        match common {
            Some(c) => ball(a, c).zip(ball(b, c)),
            None => None,
        }
    } else {
        in_world(a).zip(in_world(b))
    };
    match balls {
        Some(((ca, ra), (cb, rb))) => (ca - cb).norm() <= ra + rb,
        None => true,
    }
}

/// The groups `(static body, first pair, end pair)` of the pairs against fixed bodies and the
/// index of the first moving–moving pair, of a pair list sorted as the constructor sorts it.
fn group_pairs(pairs: &[Pair]) -> (Vec<(u32, u32, u32)>, usize) {
    let mut static_groups: Vec<(u32, u32, u32)> = Vec::new();
    let mut self_start = pairs.len();
    for (i, p) in pairs.iter().enumerate() {
        if !p.b_static {
            self_start = i;
            break;
        }
        match static_groups.last_mut() {
            Some(g) if g.0 == p.b => g.2 = i as u32 + 1,
            _ => static_groups.push((p.b, i as u32, i as u32 + 1)),
        }
    }
    (static_groups, self_start)
}
