//! Collision checking of IK answers (000 §II-A: "the IK solution has to be checked against
//! self-collisions and collisions with obstacles").
//!
//! [`GraspCheckers`]: the grasped object is removed from the scene's fixed bodies and attached to
//! the TCP by the grasp (`rel = grasp⁻¹`), one fast checker per grasp. When an IK answer reaches
//! its grasp, the attached object sits exactly where the query put it, so one checker per grasp
//! serves every object pose without rebuilding; the hand links may touch the object.
//!
//! [`ObjectPlacement`]: a free object pose against the scene's fixed bodies (parry3d), used by the
//! gradient ascent and the dual-arm IK before any arm is solved.

use parry3d_f64::query;
use parry3d_f64::shape::SharedShape;

use crate::collision::{
    parry_shape, to_parry, AttachedBody, CollisionChecker, CollisionWorld, FastChecker,
};
use crate::geometry::{Geometry, Pose};
use crate::model::Robot;

/// The links of end effector `name` (its SRDF group's links and its parent link), which may touch
/// a grasped object.
pub fn hand_links(robot: &Robot, name: &str) -> Option<Vec<usize>> {
    let ee = robot.end_effector(name)?;
    let mut links = robot
        .group(&ee.group)
        .map(|g| g.links.clone())
        .unwrap_or_default();
    if !links.contains(&ee.parent_link) {
        links.push(ee.parent_link);
    }
    Some(links)
}

/// One fast checker per grasp, with the object attached to the TCP by that grasp.
#[derive(Debug, Clone)]
pub struct GraspCheckers {
    worlds: Vec<CollisionWorld>,
    checkers: Vec<FastChecker>,
    robot: usize,
    qbuf: Vec<f64>,
}

impl GraspCheckers {
    /// Checkers for robot `robot` of `world` holding fixed body `object` at `tcp_link` by each of
    /// `grasps` (TCP in the object frame); `touch` are the links allowed to touch it; `world_q` is
    /// the world configuration giving the other robots. `None` if the world has no such body or
    /// robot.
    pub fn new(
        world: &CollisionWorld,
        robot: usize,
        object: &str,
        tcp_link: usize,
        touch: &[usize],
        grasps: &[Pose],
        world_q: &[f64],
    ) -> Option<GraspCheckers> {
        let si = world.statics.iter().position(|s| s.name == object)?;
        world.robots.get(robot)?;
        if world_q.len() != world.dof() {
            return None;
        }
        let mut base = world.clone();
        let body = base.statics.remove(si);
        for pair in &mut base.allowed {
            for id in [&mut pair.0, &mut pair.1] {
                if let crate::collision::BodyId::Static(s) = id {
                    if *s > si {
                        *s -= 1;
                    }
                }
            }
        }
        let worlds: Vec<CollisionWorld> = grasps
            .iter()
            .map(|g| {
                let mut w = base.clone();
                w.attached.push(AttachedBody {
                    name: body.name.clone(),
                    robot,
                    link: tcp_link,
                    rel: g.inverse(),
                    shapes: body.shapes.clone(),
                    touch: touch.to_vec(),
                });
                w
            })
            .collect();
        let checkers = worlds.iter().map(FastChecker::new).collect();
        Some(GraspCheckers {
            worlds,
            checkers,
            robot,
            qbuf: world_q.to_vec(),
        })
    }

    /// The world of grasp `i` (for an exact re-check).
    pub fn world(&self, i: usize) -> Option<&CollisionWorld> {
        self.worlds.get(i)
    }

    /// The world configuration for robot configuration `q` (other robots as given at creation).
    pub fn world_config(&self, q: &[f64]) -> Vec<f64> {
        let mut w = self.qbuf.clone();
        if let Some(p) = self.worlds.first().and_then(|w| w.robots.get(self.robot)) {
            w[p.offset..p.offset + q.len()].copy_from_slice(q);
        }
        w
    }

    /// True when robot configuration `q` holding the object by grasp `i` is collision-free.
    #[inline]
    pub fn is_free(&mut self, i: usize, q: &[f64]) -> bool {
        let (Some(c), Some(w)) = (self.checkers.get_mut(i), self.worlds.get(i)) else {
            return false;
        };
        let p = &w.robots[self.robot];
        if self.qbuf.len() == q.len() {
            return c.is_free(q);
        }
        self.qbuf[p.offset..p.offset + q.len()].copy_from_slice(q);
        c.is_free(&self.qbuf)
    }

    /// Collision checks performed by all checkers.
    pub fn checks(&self) -> u64 {
        self.checkers.iter().map(|c| c.checks()).sum()
    }
}

type PlacedShape = (SharedShape, Pose, nalgebra::Point3<f64>, f64);

/// Checks poses of one object against the fixed bodies of a world (exact shapes, parry3d).
#[derive(Clone)]
pub struct ObjectPlacement {
    /// Shape, its pose in the body (object) or world (statics) frame, the centre of its
    /// bounding sphere in the same frame, and the sphere radius.
    object: Vec<PlacedShape>,
    statics: Vec<PlacedShape>,
    checks: u64,
}

impl std::fmt::Debug for ObjectPlacement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectPlacement")
            .field("object_shapes", &self.object.len())
            .field("static_shapes", &self.statics.len())
            .finish()
    }
}

impl ObjectPlacement {
    /// The object `object` (a fixed body of `world`) against every other fixed body.
    pub fn new(world: &CollisionWorld, object: &str) -> Option<ObjectPlacement> {
        let body = world.statics.iter().find(|s| s.name == object)?;
        let conv = |g: &Geometry, body_pose: &Pose| {
            let (s, local) = parry_shape(g);
            let r = g.shape.bounding_radius();
            let centre = body_pose * nalgebra::Point3::from(g.origin.translation.vector);
            (s, body_pose * local, centre, r)
        };
        let object_shapes = body
            .shapes
            .iter()
            .map(|g| conv(g, &Pose::identity()))
            .collect();
        let statics = world
            .statics
            .iter()
            .filter(|s| s.name != object)
            .flat_map(|s| s.shapes.iter().map(|g| conv(g, &s.pose)))
            .collect();
        Some(ObjectPlacement {
            object: object_shapes,
            statics,
            checks: 0,
        })
    }

    /// True when the object at world pose `pose` touches no fixed body.
    pub fn is_free(&mut self, pose: &Pose) -> bool {
        self.checks += 1;
        for (os, ol, oc, or) in &self.object {
            let centre = pose * oc;
            let mut pp = None;
            for (ss, sp, sc, sr) in &self.statics {
                // Bounding spheres about the geometry origins first.
                if (centre - sc).norm() > or + sr {
                    continue;
                }
                let pp = *pp.get_or_insert_with(|| to_parry(&(pose * ol)));
                let hit = query::intersection_test(&pp, os.as_ref(), &to_parry(sp), ss.as_ref())
                    .map(|r| r.intersecting)
                    .unwrap_or(true);
                if hit {
                    return false;
                }
            }
        }
        true
    }

    /// Placement checks performed.
    pub fn checks(&self) -> u64 {
        self.checks
    }
}
