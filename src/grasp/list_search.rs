//! The per-frame finger search of a single-grasp list (paper 003 §IV-A-2, the module docs of
//! [`super::list`]): the palm placed at a grasp frame, the thumb's contacts in turn, for each
//! the other fingers finger by finger (each one's first contact, candidates ordered to oppose
//! the contacts already made), and the stability test of the contacts found.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::query;
use rand_chacha::ChaCha8Rng;

use super::grasp_object::GraspObject;
use super::hand::{transform_sphere, Hand};
use super::list::GraspListParams;
use super::surface::SurfaceSamples;
use super::wrench_space::{
    forces_one_sided, primitive_wrenches_into, quality_of_wrenches, Contact, WrenchSpaceSettings,
};
use crate::collision::to_parry;
use crate::geometry::Pose;
use crate::kinematics::NumericIk;
use crate::model::Robot;

/// One finger's contact: the finger, the nearest surface sample (its curvature), the contact
/// point and inward normal (object frame), the finger's force-ellipsoid major axis.
pub(super) struct FingerContact {
    pub finger: usize,
    pub sample: usize,
    pub point: Vector3<f64>,
    pub normal: Vector3<f64>,
    pub axis: Vector3<f64>,
}

/// A force-closure grasp of a frame, before the quality step.
pub(super) struct Candidate {
    pub palm: Pose,
    pub config: Vec<f64>,
    pub contacts: Vec<FingerContact>,
    /// Ferrari–Canny ε (> 0).
    pub epsilon: f64,
}

/// Per-thread state.
pub(super) struct Worker {
    pub q: Vec<f64>,
    pub iks: Vec<NumericIk>,
    /// Hand links placed so far: (link, pose in the object frame).
    pub placed: Vec<(usize, Pose)>,
}

/// What one frame gave: how far its search got (the counts of [`super::GraspListStats`]) and
/// its force-closure grasp, if any.
#[derive(Default)]
pub(super) struct FrameOutcome {
    pub palm_free: bool,
    pub thumb: bool,
    /// Hand closures tried (one per thumb contact).
    pub closures: usize,
    /// Closures with ≥ 3 contacts.
    pub candidates: usize,
    /// Closures with ≥ 3 contacts whose forces all push into one half-space.
    pub one_sided: usize,
    /// Contacts found per finger (over all closures).
    pub finger_contacts: Vec<usize>,
    pub candidate: Option<Candidate>,
}

/// What the search needs, shared by the worker threads.
pub(super) struct Ctx<'a> {
    pub hand: &'a Hand,
    pub robot: &'a Robot,
    pub object: &'a GraspObject,
    pub surface: &'a SurfaceSamples,
    pub params: &'a GraspListParams,
    /// The force-closure test's settings (μ, cone edges, λ = 1 / the object's radius).
    pub wrench: WrenchSpaceSettings,
    /// Base-joint fractions in search order (mid first).
    pub base_fracs: Vec<f64>,
    /// Bounding radius of each hand link's shapes (about the shape origin).
    pub bounds: std::collections::HashMap<usize, Vec<f64>>,
}

impl Ctx<'_> {
    /// Whether `link` at `pose` (object frame) collides with the object or with a placed link
    /// (a contact link is tested by its depth instead, [`Self::link_depth`]).
    pub fn link_blocked(&self, link: usize, pose: &Pose, placed: &[(usize, Pose)]) -> bool {
        let shapes = &self.hand.shapes[&link];
        let bounds = &self.bounds[&link];
        for ((s, local), b) in shapes.iter().zip(bounds) {
            let w = pose * local;
            if self.object.hits(s, &w, *b) {
                return true;
            }
            for (other, opose) in placed {
                if *other == link || self.robot.is_disabled(link, *other) {
                    continue;
                }
                let os = &self.hand.shapes[other];
                let ob = &self.bounds[other];
                for ((s2, l2), b2) in os.iter().zip(ob) {
                    let w2 = opose * l2;
                    if (w.translation.vector - w2.translation.vector).norm() > b + b2 {
                        continue;
                    }
                    let hit = query::intersection_test(
                        &to_parry(&w),
                        s.as_ref(),
                        &to_parry(&w2),
                        s2.as_ref(),
                    )
                    .map(|r| r.intersecting)
                    .unwrap_or(true);
                    if hit {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Places a finger's `links` at the current configuration; true when all are free.
    fn place_finger_links(&self, palm: &Pose, w: &mut Worker, links: &[usize]) -> bool {
        for &l in links {
            let pose = palm * self.hand.link_in_palm(l, &w.q);
            if self.link_blocked(l, &pose, &w.placed) {
                return false;
            }
            w.placed.push((l, pose));
        }
        true
    }

    /// The search of one grasp frame (palm pose `palm`, object frame): the palm must be free
    /// of the object; then each thumb contact in turn (at most `thumb_contacts`) closes the
    /// other fingers ([`Self::close_fingers`]) until the contacts are force closure.
    pub fn frame(&self, palm: &Pose, w: &mut Worker, rng: &mut ChaCha8Rng) -> FrameOutcome {
        let mut out = FrameOutcome {
            finger_contacts: vec![0; self.hand.fingers.len()],
            ..Default::default()
        };
        w.q.copy_from_slice(&self.hand.base_config());
        w.placed.clear();
        for &l in &self.hand.palm_links {
            let pose = palm * self.hand.link_in_palm(l, &w.q);
            if self.link_blocked(l, &pose, &w.placed) {
                return out;
            }
            w.placed.push((l, pose));
        }
        out.palm_free = true;
        let max = self.params.thumb_contacts;
        self.finger_contacts(0, &Vector3::zeros(), palm, w, rng, &mut |w, rng, thumb| {
            out.thumb = true;
            out.closures += 1;
            out.finger_contacts[0] += 1;
            let mark = w.placed.len();
            if let Some(contacts) = self.close_fingers(palm, w, rng, thumb) {
                for c in &contacts[1..] {
                    out.finger_contacts[c.finger] += 1;
                }
                if contacts.len() >= 3 {
                    out.candidates += 1;
                    match self.stability(&contacts) {
                        Stability::Closure(epsilon) => {
                            out.candidate = Some(Candidate {
                                palm: *palm,
                                config: self.hand.vars.iter().map(|&v| w.q[v]).collect(),
                                contacts,
                                epsilon,
                            });
                            return true;
                        }
                        Stability::OneSided => out.one_sided += 1,
                        Stability::NotClosure => {}
                    }
                }
            }
            w.placed.truncate(mark);
            out.closures >= max
        });
        out
    }

    /// The fingers after the thumb (whose contact `thumb` is placed), finger by finger: each
    /// one's first contact ([`Self::finger_contacts`]), else stretched (its rest
    /// configuration), else mid-range; `None` when a finger can be placed in none of these.
    fn close_fingers(
        &self,
        palm: &Pose,
        w: &mut Worker,
        rng: &mut ChaCha8Rng,
        thumb: FingerContact,
    ) -> Option<Vec<FingerContact>> {
        let mut contacts = vec![thumb];
        for fi in 1..self.hand.fingers.len() {
            let pushes: Vector3<f64> = contacts.iter().map(|c| c.normal).sum();
            let mut found = None;
            self.finger_contacts(fi, &pushes, palm, w, rng, &mut |_, _, c| {
                found = Some(c);
                true
            });
            match found {
                Some(c) => contacts.push(c),
                None => {
                    let f = &self.hand.fingers[fi];
                    let mark = w.placed.len();
                    let mut ok = false;
                    for cfg in [f.rest, f.mid] {
                        for (&v, x) in f.ik_vars.iter().zip(cfg) {
                            w.q[v] = x;
                        }
                        w.placed.truncate(mark);
                        if self.place_finger_links(palm, w, &f.links) {
                            ok = true;
                            break;
                        }
                    }
                    if !ok {
                        return None;
                    }
                }
            }
        }
        Some(contacts)
    }

    /// Force closure of the contacts by the Ferrari–Canny ε (point contacts with friction,
    /// centre = the object's centre of mass, λ = 1 / its radius), the wrench hull skipped when
    /// the forces alone rule force closure out.
    fn stability(&self, contacts: &[FingerContact]) -> Stability {
        let cs: Vec<Contact> = contacts
            .iter()
            .map(|k| Contact::new(k.point, k.normal))
            .collect();
        let mut wr = Vec::new();
        let Ok(lambda) = primitive_wrenches_into(&cs, &self.object.centre, &self.wrench, &mut wr)
        else {
            return Stability::NotClosure;
        };
        if forces_one_sided(&wr) {
            return Stability::OneSided;
        }
        match quality_of_wrenches(&wr, lambda) {
            Ok(g) if g.force_closure && g.epsilon > 0.0 => Stability::Closure(g.epsilon),
            _ => Stability::NotClosure,
        }
    }

    /// Finger `fi` reaching surface point `p` (outward normal `n`): the fingertip is sent to `p`
    /// by IK; the finger's other links must be free of the object and the placed links, its
    /// contact link must touch the object within the tolerance. A contact link deeper than that
    /// (a flat tip on a tilted surface) sends the target back along `n` and tries again (at most
    /// three times). The contact is where the contact link touches the object: parry's contact
    /// point on the object and its inward normal.
    #[allow(clippy::too_many_arguments)]
    fn touch_at(
        &self,
        fi: usize,
        palm: &Pose,
        ib: &Pose,
        p: Vector3<f64>,
        n: Vector3<f64>,
        w: &mut Worker,
        rng: &mut ChaCha8Rng,
        base_mark: usize,
    ) -> Option<FingerContact> {
        let f = &self.hand.fingers[fi];
        let tol = self.params.contact_tolerance;
        let ib_inv = ib.inverse();
        let mut target_p = p;
        for k in 0..3 {
            w.q[f.ik_vars[k]] = f.mid[k];
        }
        for _ in 0..4 {
            w.placed.truncate(base_mark);
            let target = Pose::from_parts(
                Translation3::from((ib_inv * Point3::from(target_p)).coords),
                UnitQuaternion::identity(),
            );
            let sol = w.iks[fi].solve(&target, &w.q, rng).ok()?;
            for k in 0..3 {
                w.q[f.ik_vars[k]] = sol[f.ik_vars[k]];
            }
            for &l in &f.links {
                if f.base_links.contains(&l) || l == f.contact_link {
                    continue;
                }
                let pose = palm * self.hand.link_in_palm(l, &w.q);
                if self.link_blocked(l, &pose, &w.placed) {
                    return None;
                }
                w.placed.push((l, pose));
            }
            let cl = f.contact_link;
            let pose = palm * self.hand.link_in_palm(cl, &w.q);
            // The contact link may enter the object by the tolerance (its depth, computed once,
            // also sets the retry's target).
            let depth = self.link_depth(cl, &pose);
            let hand_free = self.hand_free(cl, &pose, &w.placed);
            if depth > tol || !hand_free {
                // Deeper than the tolerance or hitting the hand: only depth is worth a retry.
                if depth.is_finite() && depth > tol && hand_free {
                    target_p += n * (depth - tol / 2.0);
                    continue;
                }
                return None;
            }
            let (point, normal) = self.link_touch(cl, &pose, tol)?;
            w.placed.push((cl, pose));
            // Force-ellipsoid major axis (object frame).
            let j = f.ik_chain.jacobian(self.robot, &w.q);
            let jp = j.fixed_rows::<3>(0).into_owned();
            let m: Matrix3<f64> = &jp * jp.transpose();
            let e = SymmetricEigen::new(m);
            let imin = e
                .eigenvalues
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .map_or(0, |x| x.0);
            let axis = ib.rotation * e.eigenvectors.column(imin).into_owned();
            return Some(FingerContact {
                finger: fi,
                sample: self.surface.nearest(&point),
                point,
                normal,
                axis,
            });
        }
        None
    }

    /// Deepest penetration of `link` at `pose` into the object.
    fn link_depth(&self, link: usize, pose: &Pose) -> f64 {
        let shapes = &self.hand.shapes[&link];
        let bounds = &self.bounds[&link];
        shapes
            .iter()
            .zip(bounds)
            .map(|((s, local), b)| self.object.depth(s, &(pose * local), *b))
            .fold(0.0, f64::max)
    }

    /// Whether `link` at `pose` is free of the placed hand links.
    fn hand_free(&self, link: usize, pose: &Pose, placed: &[(usize, Pose)]) -> bool {
        let shapes = &self.hand.shapes[&link];
        let bounds = &self.bounds[&link];
        shapes.iter().zip(bounds).all(|((s, local), b)| {
            let w = pose * local;
            placed.iter().all(|(other, opose)| {
                if *other == link || self.robot.is_disabled(link, *other) {
                    return true;
                }
                self.hand.shapes[other]
                    .iter()
                    .zip(&self.bounds[other])
                    .all(|((s2, l2), b2)| {
                        let w2 = opose * l2;
                        (w.translation.vector - w2.translation.vector).norm() > b + b2
                            || !query::intersection_test(
                                &to_parry(&w),
                                s.as_ref(),
                                &to_parry(&w2),
                                s2.as_ref(),
                            )
                            .map(|r| r.intersecting)
                            .unwrap_or(true)
                    })
            })
        })
    }

    /// Where `link` at `pose` touches the object (within `tol`): the contact point on the object
    /// and the inward normal; `None` when it is farther than `tol`.
    fn link_touch(
        &self,
        link: usize,
        pose: &Pose,
        tol: f64,
    ) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let shapes = &self.hand.shapes[&link];
        let mut best: Option<(f64, Vector3<f64>, Vector3<f64>)> = None;
        for (s, local) in shapes {
            if let Some((d, p, n)) = self.object.touch(s, &(pose * local), tol) {
                if best.is_none_or(|b| d < b.0) {
                    best = Some((d, p, n));
                }
            }
        }
        best.map(|b| (b.1, b.2))
    }

    /// Finger `fi`'s contacts (module docs of [`super::list`], step 2), each passed to `next`
    /// with the finger's links placed, until `next` answers true (then the placed links are
    /// left as they are; otherwise they are restored). Surface points are taken per workspace
    /// sphere (biggest first), at most `candidates_per_sphere` per sphere: for the first
    /// finger nearest the sphere's centre first; for the others, whose contacts must oppose
    /// those made (`pushes`: the sum of their inward normals), the point whose inward normal
    /// points most against `pushes` first (ties nearest the centre).
    fn finger_contacts(
        &self,
        fi: usize,
        pushes: &Vector3<f64>,
        palm: &Pose,
        w: &mut Worker,
        rng: &mut ChaCha8Rng,
        next: &mut dyn FnMut(&mut Worker, &mut ChaCha8Rng, FingerContact) -> bool,
    ) -> bool {
        let f = &self.hand.fingers[fi];
        let mark = w.placed.len();
        let fracs: &[f64] = if f.base_vars.is_empty() {
            &[0.5]
        } else {
            &self.base_fracs
        };
        let oppose = pushes.norm() > 0.0;
        for &t in fracs {
            w.placed.truncate(mark);
            for &v in &f.base_vars {
                let l = self.robot.var_limits(v);
                w.q[v] = l.lower + (l.upper - l.lower) * t;
            }
            if !self.place_finger_links(palm, w, &f.base_links) {
                continue;
            }
            let base_mark = w.placed.len();
            let ib = palm * self.hand.link_in_palm(f.ik_base, &w.q);
            for s in &f.workspace {
                let s = transform_sphere(&ib, s);
                let mut points = self.surface.within(&s.centre, s.radius);
                if oppose {
                    // Inward normal = −outward; a stable sort keeps nearest-first among ties.
                    points.sort_by(|a, b| {
                        let ka = -self.surface.normals[*a].dot(pushes);
                        let kb = -self.surface.normals[*b].dot(pushes);
                        ka.total_cmp(&kb)
                    });
                }
                for &idx in points.iter().take(self.params.candidates_per_sphere) {
                    let p = self.surface.points[idx];
                    let n = self.surface.normals[idx];
                    if let Some(c) = self.touch_at(fi, palm, &ib, p, n, w, rng, base_mark) {
                        if next(w, rng, c) {
                            return true;
                        }
                    }
                }
            }
        }
        w.placed.truncate(mark);
        false
    }
}

/// The stability of a hand closure's contacts.
enum Stability {
    Closure(f64),
    OneSided,
    NotClosure,
}
