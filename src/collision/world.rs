//! What is checked against what: the robots of a scene, its fixed bodies, attached objects and
//! the pairs that are never checked.

use std::sync::Arc;

use crate::geometry::{Geometry, Pose};
use crate::kinematics::forward;
use crate::model::{Robot, Scene};

/// A robot model placed in the world; its variables start at `offset` in a world configuration.
#[derive(Debug, Clone)]
pub struct PlacedRobot {
    pub name: String,
    pub robot: Arc<Robot>,
    pub base: Pose,
    pub offset: usize,
}

/// Whether a fixed body is an obstacle or an object resting in the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StaticKind {
    Obstacle,
    Object,
}

/// A body that does not move during a query.
#[derive(Debug, Clone)]
pub struct StaticBody {
    pub name: String,
    pub kind: StaticKind,
    /// World pose of the body.
    pub pose: Pose,
    pub shapes: Vec<Geometry>,
}

/// An object rigidly held by a robot link.
#[derive(Debug, Clone)]
pub struct AttachedBody {
    pub name: String,
    pub robot: usize,
    pub link: usize,
    /// Object frame in the link frame.
    pub rel: Pose,
    pub shapes: Vec<Geometry>,
    /// Links of the holding robot allowed to touch the object (the hand).
    pub touch: Vec<usize>,
}

/// Identifies a body of the world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BodyId {
    Link { robot: usize, link: usize },
    Static(usize),
    Attached(usize),
}

/// The robots, fixed bodies and attached objects of one query, and the pairs never checked.
#[derive(Debug, Clone)]
pub struct CollisionWorld {
    pub robots: Vec<PlacedRobot>,
    pub statics: Vec<StaticBody>,
    pub attached: Vec<AttachedBody>,
    /// Extra pairs never checked (e.g. the hand and the object it is about to grasp).
    pub allowed: Vec<(BodyId, BodyId)>,
    /// Only pairs of bodies of *different* robots (links and what they hold) are checked: no
    /// self pairs and no fixed bodies. The world of the multi-robot checks (paper 002 §IV-C,
    /// §V), where each robot's own motion was already checked against itself and the scene.
    pub robots_only: bool,
}

impl CollisionWorld {
    /// The world of a scene: all its robots; obstacles and objects as fixed bodies.
    pub fn from_scene(scene: &Scene) -> CollisionWorld {
        let mut robots = Vec::new();
        let mut offset = 0;
        for p in &scene.robots {
            robots.push(PlacedRobot {
                name: p.name.clone(),
                robot: p.robot.clone(),
                base: p.base_pose,
                offset,
            });
            offset += p.robot.dof();
        }
        let mut statics: Vec<StaticBody> = scene
            .obstacles
            .iter()
            .map(|b| StaticBody {
                name: b.name.clone(),
                kind: StaticKind::Obstacle,
                pose: b.pose,
                shapes: b.shapes.clone(),
            })
            .collect();
        statics.extend(scene.objects.iter().map(|o| StaticBody {
            name: o.body.name.clone(),
            kind: StaticKind::Object,
            pose: o.body.pose,
            shapes: o.body.shapes.clone(),
        }));
        CollisionWorld {
            robots,
            statics,
            attached: Vec::new(),
            allowed: Vec::new(),
            robots_only: false,
        }
    }

    /// A world with one robot at `base` and no environment.
    pub fn single(robot: Arc<Robot>, base: Pose) -> CollisionWorld {
        CollisionWorld {
            robots: vec![PlacedRobot {
                name: robot.name.clone(),
                robot,
                base,
                offset: 0,
            }],
            statics: Vec::new(),
            attached: Vec::new(),
            allowed: Vec::new(),
            robots_only: false,
        }
    }

    /// The same robots and held objects, checked against each other only (see
    /// [`CollisionWorld::robots_only`]): fixed bodies dropped.
    pub fn between_robots(&self) -> CollisionWorld {
        CollisionWorld {
            robots: self.robots.clone(),
            statics: Vec::new(),
            attached: self.attached.clone(),
            allowed: self
                .allowed
                .iter()
                .copied()
                .filter(|(a, b)| !matches!(a, BodyId::Static(_)) && !matches!(b, BodyId::Static(_)))
                .collect(),
            robots_only: true,
        }
    }

    /// Some robots of this world (`keep`, in that order, their variables laid out from offset 0)
    /// in its fixed bodies, with what they hold and the allowed pairs among the kept bodies.
    /// `subset(&[r])` is the world one robot plans in when the others are ignored (002 §IV: each
    /// Bimanual IK-RRT worker plans in the static environment). `None` for an unknown or
    /// repeated index.
    pub fn subset(&self, keep: &[usize]) -> Option<CollisionWorld> {
        let mut new_index = vec![None; self.robots.len()];
        let mut robots = Vec::with_capacity(keep.len());
        let mut offset = 0;
        for (i, &r) in keep.iter().enumerate() {
            let mut placed = self.robots.get(r)?.clone();
            if new_index[r].replace(i).is_some() {
                return None;
            }
            placed.offset = offset;
            offset += placed.robot.dof();
            robots.push(placed);
        }
        let mut att_map = vec![None; self.attached.len()];
        let mut attached = Vec::new();
        for (i, a) in self.attached.iter().enumerate() {
            if let Some(r) = new_index[a.robot] {
                att_map[i] = Some(attached.len());
                let mut a = a.clone();
                a.robot = r;
                attached.push(a);
            }
        }
        let map = |id: BodyId| -> Option<BodyId> {
            match id {
                BodyId::Link { robot, link } => {
                    new_index[robot].map(|robot| BodyId::Link { robot, link })
                }
                BodyId::Static(s) => Some(BodyId::Static(s)),
                BodyId::Attached(a) => att_map[a].map(BodyId::Attached),
            }
        };
        let allowed = self
            .allowed
            .iter()
            .filter_map(|&(a, b)| Some((map(a)?, map(b)?)))
            .collect();
        Some(CollisionWorld {
            robots,
            statics: self.statics.clone(),
            attached,
            allowed,
            robots_only: self.robots_only,
        })
    }

    /// The world configuration of [`Self::subset`]`(keep)` taken from one of this world.
    pub fn subset_config(&self, keep: &[usize], q: &[f64]) -> Vec<f64> {
        keep.iter()
            .flat_map(|&r| self.robot_config(r, q).iter().copied())
            .collect()
    }

    /// The robot instance a moving body belongs to (`None` for fixed bodies).
    pub fn owner(&self, id: BodyId) -> Option<usize> {
        match id {
            BodyId::Link { robot, .. } => Some(robot),
            BodyId::Attached(a) => Some(self.attached[a].robot),
            BodyId::Static(_) => None,
        }
    }

    /// Total number of variables of a world configuration.
    pub fn dof(&self) -> usize {
        self.robots.iter().map(|r| r.robot.dof()).sum()
    }

    /// The configuration of robot `r` inside a world configuration.
    #[inline]
    pub fn robot_config<'a>(&self, r: usize, q: &'a [f64]) -> &'a [f64] {
        let p = &self.robots[r];
        &q[p.offset..p.offset + p.robot.dof()]
    }

    /// Concatenates every robot's start configuration of the scene.
    pub fn start_config(scene: &Scene) -> Vec<f64> {
        scene.robots.iter().flat_map(|r| r.start_config()).collect()
    }

    /// Moves the fixed object `name` into the hand: it becomes attached to `link` of robot
    /// `robot` with its current pose relative to that link at world configuration `q`. The links
    /// of `touch` may touch it. Returns the attached index.
    pub fn attach(
        &mut self,
        name: &str,
        robot: usize,
        link: usize,
        q: &[f64],
        touch: Vec<usize>,
    ) -> Option<usize> {
        let si = self.statics.iter().position(|s| s.name == name)?;
        let p = self.robots.get(robot)?;
        let mut poses = vec![Pose::identity(); p.robot.links.len()];
        forward(&p.robot, &p.base, self.robot_config(robot, q), &mut poses);
        let body = self.statics.remove(si);
        // Indices of later statics shift by one: fix allowed pairs.
        for pair in &mut self.allowed {
            for id in [&mut pair.0, &mut pair.1] {
                if let BodyId::Static(s) = id {
                    if *s > si {
                        *s -= 1;
                    }
                }
            }
        }
        self.attached.push(AttachedBody {
            name: body.name,
            robot,
            link,
            rel: poses[link].inverse() * body.pose,
            shapes: body.shapes,
            touch,
        });
        Some(self.attached.len() - 1)
    }

    /// Never check the pair `(a, b)`.
    pub fn allow(&mut self, a: BodyId, b: BodyId) {
        self.allowed.push((a, b));
    }

    /// True when the pair is not checked: same link, SRDF-disabled pair of one robot, two links
    /// of one robot joined only by fixed joints (their relative pose never changes, so a contact
    /// is a modelling artefact — MoveIt's setup assistant disables such pairs too; e.g. the
    /// spherized Baxter's finger links overlap in every configuration), touch links of an
    /// attached object, or an allowed pair. Static–static pairs are never checked.
    pub fn is_allowed(&self, a: BodyId, b: BodyId) -> bool {
        use BodyId::*;
        match (a, b) {
            (Static(_), Static(_)) => return true,
            (
                Link {
                    robot: r1,
                    link: l1,
                },
                Link {
                    robot: r2,
                    link: l2,
                },
            ) if r1 == r2
                && (self.robots[r1].robot.is_disabled(l1, l2)
                    || rigid_root(&self.robots[r1].robot, l1)
                        == rigid_root(&self.robots[r1].robot, l2)) =>
            {
                return true
            }
            (Attached(i), Link { robot, link }) | (Link { robot, link }, Attached(i)) => {
                let at = &self.attached[i];
                if at.robot == robot && (at.link == link || at.touch.contains(&link)) {
                    return true;
                }
            }
            (Attached(i), Attached(j)) if i == j => return true,
            _ => {}
        }
        self.allowed
            .iter()
            .any(|&(x, y)| (x == a && y == b) || (x == b && y == a))
    }

    /// Human-readable name of a body: `robot/link`, `obstacle:name`, `object:name`.
    pub fn body_name(&self, id: BodyId) -> String {
        match id {
            BodyId::Link { robot, link } => format!(
                "{}/{}",
                self.robots[robot].name, self.robots[robot].robot.links[link].name
            ),
            BodyId::Static(s) => {
                let b = &self.statics[s];
                match b.kind {
                    StaticKind::Obstacle => format!("obstacle:{}", b.name),
                    StaticKind::Object => format!("object:{}", b.name),
                }
            }
            BodyId::Attached(a) => format!("object:{} (held)", self.attached[a].name),
        }
    }

    /// Every pair of bodies that a checker must test, each once, with geometry on both sides.
    /// Checkers precompute this list; its order is the order of tests.
    pub fn pairs(&self) -> Vec<(BodyId, BodyId)> {
        let mut bodies: Vec<BodyId> = Vec::new();
        for (r, p) in self.robots.iter().enumerate() {
            for (l, link) in p.robot.links.iter().enumerate() {
                if !link.collision.is_empty() {
                    bodies.push(BodyId::Link { robot: r, link: l });
                }
            }
        }
        for (a, at) in self.attached.iter().enumerate() {
            if !at.shapes.is_empty() {
                bodies.push(BodyId::Attached(a));
            }
        }
        let moving = bodies.len();
        for (s, st) in self.statics.iter().enumerate() {
            if !st.shapes.is_empty() && !self.robots_only {
                bodies.push(BodyId::Static(s));
            }
        }
        let mut out = Vec::new();
        // Moving bodies against fixed ones first: the most frequent collisions.
        for &m in &bodies[..moving] {
            for &s in &bodies[moving..] {
                if !self.is_allowed(m, s) {
                    out.push((m, s));
                }
            }
        }
        for i in 0..moving {
            for j in i + 1..moving {
                if self.robots_only && self.owner(bodies[i]) == self.owner(bodies[j]) {
                    continue;
                }
                if !self.is_allowed(bodies[i], bodies[j]) {
                    out.push((bodies[i], bodies[j]));
                }
            }
        }
        out
    }
}

/// The nearest ancestor of `link` reached through fixed joints only (the link itself when its
/// parent joint moves).
fn rigid_root(robot: &Robot, mut link: usize) -> usize {
    while let Some(j) = robot.links[link].parent_joint {
        if robot.joints[j].is_movable() {
            break;
        }
        link = robot.joints[j].parent;
    }
    link
}
