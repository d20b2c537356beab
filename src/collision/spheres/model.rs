//! Construction of the sphere checker ([`SphereChecker::new`]) from a collision world: the
//! reduced kinematic tree, the bodies and their bounding spheres, the obstacles with their
//! reach culling, the self pairs and their node groups, and the speed bounds of the certified
//! motion checks.

use nalgebra::{Matrix3, Vector3};

use super::*;
use crate::kinematics::Frame;
use crate::model::JointKind;

impl SphereChecker {
    /// The checker of `world`, or `None` when a robot link has non-sphere geometry or objects are
    /// attached. `padding` (metres, ≥ 0) is added to every robot sphere.
    pub fn new(world: &CollisionWorld, padding: f64) -> Option<SphereChecker> {
        if !(world.attached.is_empty() && padding >= 0.0 && padding.is_finite()) {
            return None;
        }
        let inflate = padding + Self::ROUNDING_MARGIN;
        let mut steps: Vec<Step> = Vec::new();
        // (body, node, local spheres) before sorting by node.
        let mut raw_bodies: Vec<(BodyId, u32, Vec<[f64; 4]>)> = Vec::new();
        // Per node: the kinematic reach from the robot root (upper bound of |t_node − t_root|)
        // and the root position.
        let mut reach: Vec<f64> = Vec::new();
        let mut root_pos: Vec<Vector3<f64>> = Vec::new();
        for (ri, p) in world.robots.iter().enumerate() {
            let robot = &p.robot;
            let n = robot.links.len();
            let mut rep = vec![u32::MAX; n];
            let mut off = vec![Frame::identity(); n];
            let base = Frame::from_pose(&p.base);
            let root = steps.len() as u32;
            steps.push(Step {
                kind: StepKind::Root,
                parent: root,
                rot: colmajor(&base.rot),
                rot_kind: OriginRot::General,
                t: f3(&base.t),
                t_terms: 0b111,
                axis: [0.0; 3],
                var: 0,
                mul: 0.0,
                off: 0.0,
                travel: 0.0,
                bodies: (0, 0),
            });
            reach.push(0.0);
            root_pos.push(base.t);
            if n == 0 {
                continue;
            }
            rep[0] = root;
            for j in &robot.joints {
                let (pl, cl) = (j.parent, j.child);
                if rep[pl] == u32::MAX {
                    return None; // not in tree order
                }
                let origin = off[pl].mul(&Frame::from_pose(&j.origin));
                let (var, mul, o) = match (j.var, j.mimic) {
                    (Some(v), _) => (Some(v), 1.0, 0.0),
                    (None, Some(m)) => (Some(m.var), m.multiplier, m.offset),
                    _ => (None, 0.0, 0.0),
                };
                let kind = match (j.kind, var) {
                    (JointKind::Fixed, _) | (_, None) => None,
                    (JointKind::Prismatic, _) => Some(StepKind::Prismatic),
                    (JointKind::Revolute | JointKind::Continuous, _) => {
                        let a = j.axis.into_inner();
                        let ax = if (a - Vector3::x()).norm() < 1e-12 {
                            Axis::X
                        } else if (a - Vector3::y()).norm() < 1e-12 {
                            Axis::Y
                        } else if (a - Vector3::z()).norm() < 1e-12 {
                            Axis::Z
                        } else {
                            Axis::General
                        };
                        Some(StepKind::Revolute(ax))
                    }
                };
                match kind {
                    None => {
                        rep[cl] = rep[pl];
                        off[cl] = origin;
                    }
                    Some(kind) => {
                        let node = steps.len() as u32;
                        let parent = rep[pl];
                        let travel = match (kind, var) {
                            (StepKind::Prismatic, Some(v)) => {
                                let lim = robot.var_limits(v);
                                if lim.bounded {
                                    (mul * lim.lower + o).abs().max((mul * lim.upper + o).abs())
                                } else {
                                    f64::INFINITY
                                }
                            }
                            _ => 0.0,
                        };
                        let (t, t_terms) = origin_terms(&origin.t);
                        steps.push(Step {
                            kind,
                            parent,
                            rot: colmajor(&origin.rot),
                            rot_kind: OriginRot::classify(&origin.rot),
                            t,
                            t_terms,
                            axis: f3(&j.axis.into_inner()),
                            var: (p.offset + var.unwrap_or(0)) as u32,
                            mul: mul as f32,
                            off: o as f32,
                            travel,
                            bodies: (0, 0),
                        });
                        let r = if kind == StepKind::Prismatic {
                            f64::INFINITY
                        } else {
                            reach[parent as usize] + origin.t.norm()
                        };
                        reach.push(r);
                        root_pos.push(base.t);
                        rep[cl] = node;
                        off[cl] = Frame::identity();
                    }
                }
            }
            for (li, link) in robot.links.iter().enumerate() {
                if link.collision.is_empty() {
                    continue;
                }
                if rep[li] == u32::MAX {
                    return None;
                }
                let mut sp = Vec::new();
                for g in &link.collision {
                    let Shape::Sphere { radius } = g.shape else {
                        return None;
                    };
                    let c = off[li].transform_point(&g.origin.translation.vector);
                    sp.push([c.x, c.y, c.z, radius + inflate]);
                }
                raw_bodies.push((
                    BodyId::Link {
                        robot: ri,
                        link: li,
                    },
                    rep[li],
                    sp,
                ));
            }
        }
        raw_bodies.sort_by_key(|b| b.1);

        // Obstacles: one per static shape.
        let mut obstacles = Vec::new();
        let mut obstacle_static = Vec::new();
        let mut obstacle_bound: Vec<(Vector3<f64>, f64)> = Vec::new();
        for (si, st) in world.statics.iter().enumerate() {
            for g in &st.shapes {
                let pose = st.pose * g.origin;
                let c = pose.translation.vector;
                let rot = *pose.rotation.to_rotation_matrix().matrix();
                let axis = rot.column(2).into_owned();
                let rt = |rot: &Matrix3<f64>| {
                    let mut o = [[0.0f32; 3]; 3];
                    for (r, row) in o.iter_mut().enumerate() {
                        for (k, v) in row.iter_mut().enumerate() {
                            *v = rot[(r, k)] as f32;
                        }
                    }
                    // Rows of R = columns of Rᵀ: local_k = Σ_r R[r][k] (x − c)_r; store by k.
                    let mut t = [[0.0f32; 3]; 3];
                    for k in 0..3 {
                        for r in 0..3 {
                            t[k][r] = o[r][k];
                        }
                    }
                    t
                };
                let (o, bound) = match &g.shape {
                    Shape::Sphere { radius } => (
                        Obs::Sphere {
                            c: f3(&c),
                            r: *radius as f32,
                        },
                        (c, *radius),
                    ),
                    Shape::Box { half_extents } => (
                        Obs::Box {
                            c: f3(&c),
                            rt: rt(&rot),
                            half: f3(half_extents),
                        },
                        (c, half_extents.norm()),
                    ),
                    Shape::Cylinder {
                        radius,
                        half_length,
                    } => (
                        Obs::Cylinder {
                            c: f3(&c),
                            axis: f3(&axis),
                            r: *radius as f32,
                            h: *half_length as f32,
                        },
                        (c, (radius * radius + half_length * half_length).sqrt()),
                    ),
                    Shape::Capsule {
                        radius,
                        half_length,
                    } => (
                        Obs::Capsule {
                            c: f3(&c),
                            axis: f3(&axis),
                            r: *radius as f32,
                            h: *half_length as f32,
                        },
                        (c, radius + half_length),
                    ),
                    Shape::Mesh(m) => {
                        if m.vertices.is_empty() {
                            continue;
                        }
                        // The boxes of its cover (a solid's, or the box around its vertices).
                        for (mid, half) in m.cover() {
                            let mid = c + rot * mid;
                            obstacles.push(Obs::Box {
                                c: f3(&mid),
                                rt: rt(&rot),
                                half: f3(&half),
                            });
                            obstacle_static.push(si as u32);
                            obstacle_bound.push((mid, half.norm()));
                        }
                        continue;
                    }
                };
                obstacles.push(o);
                obstacle_static.push(si as u32);
                obstacle_bound.push(bound);
            }
        }

        let obstacle_sphere: Vec<[f32; 4]> = obstacle_bound
            .iter()
            .map(|(c, r)| {
                let scale = 1.0 + c.norm() + r;
                [
                    c.x as f32,
                    c.y as f32,
                    c.z as f32,
                    (r + 1e-5 * scale) as f32,
                ]
            })
            .collect();
        let pairs = world.pairs();
        // Moving bodies by a dense index (links of each robot in turn, then attached objects),
        // and per moving body the fixed bodies it is checked against: set-up ran SipHash
        // lookups per pair and scanned every pair per (body, obstacle) before (measured,
        // callgrind, UR5-like problems: 168 k instructions per checker, most of them those).
        let link_base: Vec<usize> = world
            .robots
            .iter()
            .scan(0, |n, p| {
                let b = *n;
                *n += p.robot.links.len();
                Some(b)
            })
            .collect();
        let n_links: usize = world.robots.iter().map(|p| p.robot.links.len()).sum();
        let dense = |id: BodyId| match id {
            BodyId::Link { robot, link } => Some(link_base[robot] + link),
            BodyId::Attached(a) => Some(n_links + a),
            BodyId::Static(_) => None,
        };
        let n_dense = n_links + world.attached.len();
        let n_statics = world.statics.len();
        let mut checked_static = vec![false; n_dense * n_statics];
        for &(a, b) in &pairs {
            if let (Some(m), BodyId::Static(s)) = (dense(a), b) {
                checked_static[m * n_statics + s] = true;
            }
        }
        let mut bodies = Vec::new();
        let mut spheres = Vec::new();
        let mut body_obstacles = Vec::new();
        for (id, node, sp) in &raw_bodies {
            // Bounding sphere: centre of the box around the spheres.
            let mut lo = Vector3::repeat(f64::INFINITY);
            let mut hi = Vector3::repeat(f64::NEG_INFINITY);
            for s in sp {
                let c = Vector3::new(s[0], s[1], s[2]);
                lo = lo.inf(&c.add_scalar(-s[3]));
                hi = hi.sup(&c.add_scalar(s[3]));
            }
            let bc = (lo + hi) * 0.5;
            let br = sp
                .iter()
                .map(|s| (Vector3::new(s[0], s[1], s[2]) - bc).norm() + s[3])
                .fold(0.0, f64::max)
                * (1.0 + 1e-6)
                + 1e-6;
            let first_s = spheres.len() as u32;
            spheres.extend(
                sp.iter()
                    .map(|s| [s[0] as f32, s[1] as f32, s[2] as f32, s[3] as f32]),
            );
            let first_o = body_obstacles.len() as u32;
            let n = *node as usize;
            let body_reach = reach[n] + bc.norm() + br;
            let row = dense(*id).map(|m| m * n_statics);
            for (oi, &si) in obstacle_static.iter().enumerate() {
                let checked = row.is_some_and(|r| checked_static[r + si as usize]);
                if !checked {
                    continue;
                }
                let (oc, orad) = obstacle_bound[oi];
                if (oc - root_pos[n]).norm() - orad > body_reach * (1.0 + 1e-6) + 1e-4 {
                    continue; // out of this link's reach
                }
                body_obstacles.push(oi as u32);
            }
            // Same-kind obstacles in a row: the per-obstacle dispatch branch predicts well.
            let kind = |o: &Obs| match o {
                Obs::Box { .. } => 0,
                Obs::Cylinder { .. } => 1,
                Obs::Sphere { .. } => 2,
                Obs::Capsule { .. } => 3,
            };
            body_obstacles[first_o as usize..].sort_by_key(|&oi| kind(&obstacles[oi as usize]));
            bodies.push(Body {
                id: *id,
                node: *node,
                bc: f3(&bc),
                br: br as f32,
                spheres: (first_s, spheres.len() as u32),
                obstacles: (first_o, body_obstacles.len() as u32),
            });
        }
        for (si, s) in steps.iter_mut().enumerate() {
            let first = bodies.partition_point(|b: &Body| (b.node as usize) < si) as u32;
            let end = bodies.partition_point(|b: &Body| (b.node as usize) <= si) as u32;
            s.bodies = (first, end);
        }
        // By dense id (a linear search per pair costs O(bodies · pairs) on robots of hundreds of
        // links).
        let mut by_id = vec![usize::MAX; n_dense];
        for (i, b) in bodies.iter().enumerate() {
            if let Some(m) = dense(b.id) {
                if by_id[m] == usize::MAX {
                    by_id[m] = i;
                }
            }
        }
        let index = |id: BodyId| dense(id).map(|m| by_id[m]).filter(|&i| i != usize::MAX);
        let mut self_pairs = Vec::new();
        for &(a, b) in &pairs {
            if let (Some(ia), Some(ib)) = (index(a), index(b)) {
                // Later body second (its spheres are computed last).
                self_pairs.push((ia.min(ib) as u32, ia.max(ib) as u32));
            }
        }
        // The pairs of a node pair with at least NODE_CULL_MIN_PAIRS pairs become one group
        // (at the place of its first pair, pairs in order within); every other pair stays in
        // its place as a group of one: the test order matters when a state collides.
        let mut pair_group_end: Vec<u32> = Vec::new();
        {
            let node_of = |b: u32| bodies[b as usize].node;
            let key = |&(a, b): &(u32, u32)| (node_of(a), node_of(b));
            // The pairs of each node pair, in order (one pass: counting per pair would cost
            // O(pairs²)).
            let mut members: std::collections::HashMap<(u32, u32), Vec<(u32, u32)>> =
                std::collections::HashMap::new();
            for p in &self_pairs {
                members.entry(key(p)).or_default().push(*p);
            }
            let mut grouped = Vec::with_capacity(self_pairs.len());
            let mut done: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
            for p in &self_pairs {
                let k = key(p);
                let group = &members[&k];
                if group.len() < Self::NODE_CULL_MIN_PAIRS as usize {
                    grouped.push(*p);
                    pair_group_end.push(0);
                } else if done.insert(k) {
                    let first = grouped.len();
                    grouped.extend(group.iter().copied());
                    pair_group_end.resize(grouped.len(), 0);
                    pair_group_end[first] = grouped.len() as u32;
                }
            }
            self_pairs = grouped;
        }
        let node_sphere: Vec<[f32; 4]> = steps
            .iter()
            .map(|s| {
                let bs = &bodies[s.bodies.0 as usize..s.bodies.1 as usize];
                if bs.is_empty() {
                    return [0.0; 4];
                }
                let v = |b: &Body| Vector3::new(b.bc[0] as f64, b.bc[1] as f64, b.bc[2] as f64);
                let mut lo = Vector3::repeat(f64::INFINITY);
                let mut hi = Vector3::repeat(f64::NEG_INFINITY);
                for b in bs {
                    lo = lo.inf(&v(b).add_scalar(-(b.br as f64)));
                    hi = hi.sup(&v(b).add_scalar(b.br as f64));
                }
                let c = (lo + hi) * 0.5;
                let r = bs
                    .iter()
                    .map(|b| (v(b) - c).norm() + b.br as f64)
                    .fold(0.0, f64::max);
                let r = r * (1.0 + 1e-6) + Self::ROUNDING_MARGIN;
                [c.x as f32, c.y as f32, c.z as f32, r as f32]
            })
            .collect();
        let nb = bodies.len();
        let ns = spheres.len();
        let n_nodes = steps.len();
        // Speed bounds: a sphere centre c riding on node k moves, per unit of a revolute
        // variable of an ancestor node i, at most its distance to i's axis (a line through
        // o_i). In node k's own frame that distance is exactly |c × a_k| (a_k the unit axis);
        // for an ancestor i, whose child node j on the path sits at t_j (in i's frame), it is
        // at most |t_j × a_i| + D_j, where D_j = max |c − o_j| in node j's frame and
        // D_parent = D_j + |t_j| (+ prismatic travel): the part of the chain below j turns
        // about j's axis, so its points stay within D_j of o_j, and only the part of t_j across
        // i's axis counts (never more than the distance to o_i; on the Panda, the hand's bodies
        // about joint 7 get 0.08 m/rad instead of 0.22). Per body, its movable ancestor joints
        // from the body's node up to the root (`chain`, ranges in `chain_range`): the world
        // variable and that bound (m/rad or m/m); summed per variable into `var_w` and, below
        // each self pair's common ancestor, `pair_w`.
        let mut chain: Vec<(u32, f64)> = Vec::new();
        let mut chain_range = Vec::with_capacity(nb);
        let mut cum_off = Vec::with_capacity(nb);
        let mut certifiable = true;
        let mut cum_len = 0u32;
        let v3 = |a: &[f32; 3]| Vector3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2]));
        let across =
            |p: &Vector3<f64>, axis: &[f32; 3]| crate::geometry::distance_from_axis(p, &v3(axis));
        for body in &bodies {
            let first = chain.len() as u32;
            let centres: Vec<Vector3<f64>> = spheres
                [body.spheres.0 as usize..body.spheres.1 as usize]
                .iter()
                .map(|s| v3(&[s[0], s[1], s[2]]))
                .collect();
            let mut d = centres.iter().map(|c| c.norm()).fold(0.0, f64::max);
            let mut k = body.node as usize;
            // Bound on the distance of the centres to node k's axis.
            let own = &steps[k];
            let mut lever = centres
                .iter()
                .map(|c| across(c, &own.axis))
                .fold(0.0, f64::max);
            loop {
                let st = &steps[k];
                let mul = f64::from(st.mul).abs();
                let w = match st.kind {
                    StepKind::Root => break,
                    StepKind::Revolute(_) => mul * lever,
                    StepKind::Prismatic => mul,
                };
                chain.push((st.var, w * (1.0 + 1e-5)));
                let t = v3(&st.t);
                let parent = &steps[st.parent as usize];
                lever = across(&t, &parent.axis) + d + st.travel;
                d += t.norm() + st.travel;
                certifiable &= d.is_finite() && w.is_finite();
                k = st.parent as usize;
            }
            chain_range.push((first, chain.len() as u32));
            cum_off.push(cum_len);
            cum_len += chain.len() as u32 - first + 1;
        }
        // Position in a body's chain of the first ancestor shared with the other body.
        let below_common = |a: usize, b: usize| -> u32 {
            let mut up_b = vec![false; steps.len()];
            let mut k = bodies[b].node as usize;
            loop {
                up_b[k] = true;
                if steps[k].kind == StepKind::Root {
                    break;
                }
                k = steps[k].parent as usize;
            }
            let mut k = bodies[a].node as usize;
            let mut n = 0;
            while !up_b[k] && steps[k].kind != StepKind::Root {
                n += 1;
                k = steps[k].parent as usize;
            }
            cum_off[a] + n
        };
        let dof = world.dof();
        let stride = nb.div_ceil(4) * 4;
        let mut var_w = vec![0.0f64; dof * stride];
        for (bi, &(c0, c1)) in chain_range.iter().enumerate() {
            for &(v, w) in &chain[c0 as usize..c1 as usize] {
                var_w[v as usize * stride + bi] += w;
            }
        }
        let n_pairs = self_pairs.len();
        let mut pair_w = vec![0.0f64; dof * n_pairs];
        for (pi, &(a, b)) in self_pairs.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            for (x, below) in [(a, below_common(a, b)), (b, below_common(b, a))] {
                let c0 = chain_range[x].0 as usize;
                let n = (below - cum_off[x]) as usize;
                for &(v, w) in &chain[c0..c0 + n] {
                    pair_w[pi * dof + v as usize] += w;
                }
            }
        }
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        let (acc_static_node, acc_static_body) = chord::accel_statics(&steps, &bodies, &spheres);
        let mut acc_node_dmax = vec![-1.0f64; n_nodes];
        for (b, body) in bodies.iter().enumerate() {
            let m = &mut acc_node_dmax[body.node as usize];
            *m = m.max(acc_static_body[b].0);
        }
        let acc_steps = chord::acc_steps(&steps, &acc_static_node);
        let acc_amax = chord::acc_amax_nodes(&steps, &acc_static_node, &acc_node_dmax);
        let node_anchor: Vec<(u32, f64)> = steps
            .iter()
            .zip(&node_sphere)
            .map(|(st, ns)| {
                if st.bodies.0 == st.bodies.1 {
                    return (u32::MAX, 0.0);
                }
                let bc = bodies[st.bodies.0 as usize].bc;
                let d = Vector3::new(
                    f64::from(ns[0]) - f64::from(bc[0]),
                    f64::from(ns[1]) - f64::from(bc[1]),
                    f64::from(ns[2]) - f64::from(bc[2]),
                );
                (st.bodies.0, d.norm() * (1.0 + 1e-6) + 1e-9)
            })
            .collect();
        let mut checker = SphereChecker {
            world: world.clone(),
            qv: vec![[0.0; LANES]; world.dof()],
            frames: vec![[[0.0; LANES]; 12]; steps.len()],
            steps,
            bcw: vec![[[0.0; LANES]; 3]; nb],
            sw: vec![[[0.0; LANES]; 3]; ns],
            swm: vec![[[0.0; LANES]; 3]; ns],
            swh: vec![[0.0; LANES]; ns],
            sw_epoch: vec![0; nb],
            chord_epoch: vec![0; nb],
            ncw: vec![[[0.0; LANES]; 3]; n_nodes],
            ncw_epoch: vec![0; n_nodes],
            ninfl: vec![0.0; n_nodes],
            bodies,
            spheres,
            #[cfg(target_arch = "x86_64")]
            obstacles_wide: obstacles.iter().map(avx8::ObsWide::of).collect(),
            obstacles,
            obstacle_static,
            body_obstacle_sphere: body_obstacles
                .iter()
                .map(|&oi| obstacle_sphere[oi as usize])
                .collect(),
            body_obstacles,
            self_pairs,
            pair_group_end,
            node_cull: true,
            node_sphere,
            epoch: 0,
            checks: 0,
            avx2,
            inflate,
            pair_len: vec![0.0; n_pairs],
            pair_len_epoch: vec![0; n_pairs],
            seg_epoch: 0,
            var_w,
            pair_w,
            certifiable,
            seg_len: vec![0.0; stride],
            infl: vec![0.0; nb],
            pair_scale: 0.0,
            seg_dq: vec![0.0; world.dof()],
            hot_body: u32::MAX,
            warm_body: u32::MAX,
            hot_first: true,
            hot_pair: (u32::MAX, u32::MAX),
            tight_log: Vec::new(),
            tight_states: Vec::new(),
            refine: Vec::new(),
            refine_needed: Vec::new(),
            focus_pool: Vec::new(),
            focus: true,
            pair_keep: Vec::new(),
            certify_counts: Default::default(),
            uncertified: false,
            chord: true,
            acc_steps,
            acc_amax,
            acc_static_body,
            acc_node: vec![[0.0; 6]; n_nodes],
            seg_acc: vec![0.0; nb],
            acc_epoch: vec![0; nb],
            acc_seg: 0,
            chord_k: 0.0,
            dl_call: 0,
            dl_epoch: vec![0; nb],
            node_dl_epoch: vec![0; n_nodes],
            node_acc_epoch: vec![0; n_nodes],
            node_anchor,
            node_acc: vec![0.0; n_nodes],
            node_dl: vec![0.0; n_nodes],
        };
        checker.init_roots();
        Some(checker)
    }
}

fn colmajor(m: &Matrix3<f64>) -> [f32; 9] {
    let mut o = [0.0f32; 9];
    for c in 0..3 {
        for r in 0..3 {
            o[c * 3 + r] = m[(r, c)] as f32;
        }
    }
    o
}
