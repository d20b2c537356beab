//! Exact collision checking on the real geometry with parry3d-f64 shapes.
//!
//! Owns [`ExactChecker`], the reference checker: every shape of the world (boxes, cylinders,
//! spheres, capsules, meshes) is converted once into a parry shape in f64 and each checked pair
//! of bodies is tested shape against shape with parry's narrow phase. Tests use it as the ground
//! truth for the fast checker, and the server uses it to re-validate finished plans.
//!
//! It is slow compared with `FastChecker` (dynamic dispatch, GJK on convex shapes, f64): it must
//! not be used in planner hot loops.
//!
//! A closed, consistently oriented mesh ([`crate::geometry::Solid`]) is checked as the true
//! solid: its surface as parry's `TriMesh` (triangle against shape) and its inside by winding
//! number, so a shape with no surface contact is tested at one of its points for lying inside
//! the mesh and the mesh at one of its vertices for lying inside the shape; a finger between
//! two legs of a statuette is free. Any other mesh is replaced by the convex hull of its
//! vertices, a conservative superset (a body inside a closed mesh, or in one of its
//! concavities, is reported as colliding); if the hull cannot be built (degenerate or flat
//! vertex set) the box of the mesh's bounding box is used instead, which is conservative too.
//! Any shape pair parry cannot answer is treated as colliding.

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use parry3d_f64::math::{Pose as PPose, Rot3, Vector as PVector};
use parry3d_f64::query;
use parry3d_f64::shape::{ConvexPolyhedron, SharedShape};

use super::{BodyId, CollisionChecker, CollisionWorld, Contact};
use crate::geometry::{Geometry, Pose, Shape, Solid};
use crate::kinematics::forward;
use crate::model::Robot;

/// Converts a nalgebra isometry into a parry (glam) pose.
#[inline]
pub(crate) fn to_parry(p: &Pose) -> PPose {
    let t = &p.translation.vector;
    let q = &p.rotation.as_ref().coords; // (i, j, k, w)
    PPose::from_parts(
        PVector::new(t.x, t.y, t.z),
        Rot3::from_xyzw(q[0], q[1], q[2], q[3]),
    )
}

/// Converts a nalgebra vector into a parry (glam) vector.
#[inline]
fn to_pvec(v: &Vector3<f64>) -> PVector {
    PVector::new(v.x, v.y, v.z)
}

/// One parry shape with its pose in the body frame and its bounding sphere.
#[derive(Clone)]
struct ShapeRec {
    shape: SharedShape,
    /// Pose of the parry shape in the body frame (the geometry origin, plus the z→y axis fix of
    /// cylinders or the box centre of a mesh fallback).
    local: Pose,
    /// Radius of a sphere centred on the parry shape's origin holding the shape.
    radius: f64,
    /// A solid mesh (its parry shape is the surface only, a `TriMesh`): the inside test.
    solid: Option<Arc<Solid>>,
    /// A point of the shape, in the parry shape's frame (containment tests).
    witness: PVector,
}

/// Surfaces (`TriMesh`) of the solids converted so far, by solid: a checker is built per
/// world (the pick-and-place task builds one per phase world and per key-configuration search),
/// and the `TriMesh`'s BVH of a 1 300-triangle statuette was 7 % of a task's instructions. The
/// same solid gives the same `TriMesh` (a pure function of its vertices and triangles); entries
/// of dropped solids are pruned on insertion.
static SURFACES: std::sync::Mutex<Vec<(std::sync::Weak<Solid>, SharedShape)>> =
    std::sync::Mutex::new(Vec::new());

/// The surface of `solid` as parry's `TriMesh` (cached, [`SURFACES`]); `None` when parry
/// refuses the triangles.
fn solid_surface(solid: &Arc<Solid>) -> Option<SharedShape> {
    let cached = |c: &[(std::sync::Weak<Solid>, SharedShape)]| {
        c.iter()
            .find(|(w, _)| std::ptr::eq(w.as_ptr(), Arc::as_ptr(solid)))
            .map(|(_, s)| s.clone())
    };
    if let Ok(c) = SURFACES.lock() {
        if let Some(s) = cached(&c) {
            return Some(s);
        }
    }
    let pts: Vec<PVector> = solid.vertices.iter().map(|v| to_pvec(&v.coords)).collect();
    let tm = SharedShape::trimesh(pts, solid.triangles.clone()).ok()?;
    if let Ok(mut c) = SURFACES.lock() {
        c.retain(|(w, _)| w.strong_count() > 0);
        if cached(&c).is_none() {
            c.push((Arc::downgrade(solid), tm.clone()));
        }
    }
    Some(tm)
}

/// [`convert`], except that a solid mesh gives its surface (parry's `TriMesh`) and its solid.
fn convert_solid(shape: &Shape) -> (SharedShape, Pose, f64, Option<Arc<Solid>>) {
    if let Shape::Mesh(m) = shape {
        if let Ok(solid) = &m.solid {
            if let Some(tm) = solid_surface(solid) {
                return (tm, Pose::identity(), m.max_radius(), Some(solid.clone()));
            }
        }
    }
    let (s, fix, r) = convert(shape);
    (s, fix, r, None)
}

/// Converts one geometry, a mesh as its convex hull (or box). Returns the parry shape, the extra
/// pose between the geometry frame and the parry shape frame, and the bounding radius about the
/// parry shape's origin.
fn convert(shape: &Shape) -> (SharedShape, Pose, f64) {
    match shape {
        Shape::Box { half_extents } => (
            SharedShape::cuboid(half_extents.x, half_extents.y, half_extents.z),
            Pose::identity(),
            shape.bounding_radius(),
        ),
        Shape::Cylinder {
            radius,
            half_length,
        } => (
            // parry's cylinder axis is its local y: +90° about x maps y onto our z.
            SharedShape::cylinder(*half_length, *radius),
            Pose::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
            ),
            shape.bounding_radius(),
        ),
        Shape::Sphere { radius } => (
            SharedShape::ball(*radius),
            Pose::identity(),
            shape.bounding_radius(),
        ),
        Shape::Capsule {
            radius,
            half_length,
        } => (
            SharedShape::capsule_z(*half_length, *radius),
            Pose::identity(),
            shape.bounding_radius(),
        ),
        Shape::Mesh(m) => {
            let pts: Vec<PVector> = m.vertices.iter().map(|v| to_pvec(&v.coords)).collect();
            let hull = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                ConvexPolyhedron::from_convex_hull(&pts)
            }))
            .ok()
            .flatten();
            match hull {
                Some(h) => (
                    SharedShape::new(h),
                    Pose::identity(),
                    shape.bounding_radius(),
                ),
                None => {
                    // Fallback: the box of the vertices' bounding box (conservative).
                    let (lo, hi) = m.aabb();
                    let centre = (lo + hi) * 0.5;
                    let half = ((hi - lo) * 0.5).map(|h| h.max(1e-9));
                    (
                        SharedShape::cuboid(half.x, half.y, half.z),
                        Pose::from_parts(Translation3::from(centre), UnitQuaternion::identity()),
                        half.norm(),
                    )
                }
            }
        }
    }
}

/// The parry shape of a geometry and its pose in the body frame (cylinder axis fix and mesh
/// hull/box placement included): the convex conversion of the parry-based checks outside the
/// exact checker (a mesh as its hull, conservative).
pub(crate) fn parry_shape(g: &Geometry) -> (SharedShape, Pose) {
    let (shape, fix, _) = convert(&g.shape);
    (shape, g.origin * fix)
}

/// Whether [`ExactChecker`] models `g` as a non-convex solid (a mesh: its surface and its
/// inside), which no convex shape stands for. Every other geometry it tests as [`parry_shape`]
/// gives it, so a test made with those shapes alone finds a collision only where the exact
/// checker finds it too.
pub(crate) fn is_solid_mesh(g: &Geometry) -> bool {
    match &g.shape {
        Shape::Mesh(m) => m
            .solid
            .as_ref()
            .is_ok_and(|solid| solid_surface(solid).is_some()),
        _ => false,
    }
}

fn convert_all(geoms: &[Geometry], out: &mut Vec<ShapeRec>) {
    for g in geoms {
        let (shape, fix, radius, solid) = convert_solid(&g.shape);
        let witness = match (&solid, shape.as_convex_polyhedron()) {
            (Some(s), _) => s
                .vertices
                .first()
                .map_or(PVector::ZERO, |v| to_pvec(&v.coords)),
            (None, Some(p)) => p.points().first().copied().unwrap_or(PVector::ZERO),
            // Primitives are centred on their frame's origin.
            (None, None) => PVector::ZERO,
        };
        out.push(ShapeRec {
            shape,
            local: g.origin * fix,
            radius,
            solid,
            witness,
        });
    }
}

/// Where a body's pose comes from.
#[derive(Clone, Copy)]
enum Frame {
    /// Link `link` of robot `robot`.
    Link { robot: usize, link: usize },
    /// Rigidly attached to a link: `link pose · rel`.
    Attached {
        robot: usize,
        link: usize,
        rel: Pose,
    },
    /// Fixed world pose (shape poses computed once).
    Static,
}

#[derive(Clone)]
struct BodyRec {
    frame: Frame,
    /// Range of the body's shapes in the flat shape arrays.
    first: usize,
    end: usize,
}

/// Reference collision checker on the exact geometry (parry3d-f64); see the module docs.
/// Not for planner hot loops.
#[derive(Clone)]
pub struct ExactChecker {
    robots: Vec<(Arc<Robot>, Pose, usize)>,
    /// FK buffer per robot.
    fk: Vec<Vec<Pose>>,
    bodies: Vec<BodyRec>,
    /// Names of the bodies (`CollisionWorld::body_name`).
    names: Vec<String>,
    shapes: Vec<ShapeRec>,
    /// World pose of every shape at the last updated configuration.
    world: Vec<PPose>,
    /// World centre of every shape's bounding sphere.
    centres: Vec<Vector3<f64>>,
    /// Checked pairs as body indices, in `CollisionWorld::pairs` order.
    pairs: Vec<(usize, usize)>,
    dof: usize,
    checks: u64,
}

impl ExactChecker {
    /// Builds the checker for a world: converts every shape once and precomputes the pairs to
    /// test. Holds `Arc`s of the robots and clones nothing else from `world`.
    pub fn new(world: &CollisionWorld) -> ExactChecker {
        let mut bodies = Vec::new();
        let mut names = Vec::new();
        let mut shapes = Vec::new();
        let mut index: HashMap<BodyId, usize> = HashMap::new();
        let mut add = |id: BodyId, frame: Frame, geoms: &[Geometry], shapes: &mut Vec<ShapeRec>| {
            let first = shapes.len();
            convert_all(geoms, shapes);
            index.insert(id, bodies.len());
            names.push(world.body_name(id));
            bodies.push(BodyRec {
                frame,
                first,
                end: shapes.len(),
            });
        };
        for (r, p) in world.robots.iter().enumerate() {
            for (l, link) in p.robot.links.iter().enumerate() {
                if !link.collision.is_empty() {
                    let frame = Frame::Link { robot: r, link: l };
                    add(
                        BodyId::Link { robot: r, link: l },
                        frame,
                        &link.collision,
                        &mut shapes,
                    );
                }
            }
        }
        for (a, at) in world.attached.iter().enumerate() {
            if !at.shapes.is_empty() {
                let frame = Frame::Attached {
                    robot: at.robot,
                    link: at.link,
                    rel: at.rel,
                };
                add(BodyId::Attached(a), frame, &at.shapes, &mut shapes);
            }
        }
        let first_static = shapes.len();
        for (s, st) in world.statics.iter().enumerate() {
            if !st.shapes.is_empty() {
                add(BodyId::Static(s), Frame::Static, &st.shapes, &mut shapes);
            }
        }
        let mut world_poses = vec![PPose::IDENTITY; shapes.len()];
        let mut centres = vec![Vector3::zeros(); shapes.len()];
        // Static shapes: world poses once.
        for (s, st) in world.statics.iter().enumerate() {
            if let Some(&b) = index.get(&BodyId::Static(s)) {
                let rec = &bodies[b];
                for i in rec.first..rec.end {
                    debug_assert!(i >= first_static);
                    let w = st.pose * shapes[i].local;
                    world_poses[i] = to_parry(&w);
                    centres[i] = w.translation.vector;
                }
            }
        }
        let pairs = world
            .pairs()
            .into_iter()
            .filter_map(|(a, b)| Some((*index.get(&a)?, *index.get(&b)?)))
            .collect();
        ExactChecker {
            robots: world
                .robots
                .iter()
                .map(|p| (p.robot.clone(), p.base, p.offset))
                .collect(),
            fk: world
                .robots
                .iter()
                .map(|p| vec![Pose::identity(); p.robot.links.len()])
                .collect(),
            bodies,
            names,
            shapes,
            world: world_poses,
            centres,
            pairs,
            dof: world.dof(),
            checks: 0,
        }
    }

    /// Number of body pairs tested per configuration.
    pub fn num_pairs(&self) -> usize {
        self.pairs.len()
    }

    /// Computes FK of every robot and the world pose of every moving shape.
    fn update(&mut self, q: &[f64]) {
        assert_eq!(
            q.len(),
            self.dof,
            "world configuration has {} values, expected {}",
            q.len(),
            self.dof
        );
        for (r, (robot, base, offset)) in self.robots.iter().enumerate() {
            forward(
                robot,
                base,
                &q[*offset..*offset + robot.dof()],
                &mut self.fk[r],
            );
        }
        for b in &self.bodies {
            let pose = match b.frame {
                Frame::Link { robot, link } => self.fk[robot][link],
                Frame::Attached { robot, link, rel } => self.fk[robot][link] * rel,
                Frame::Static => continue,
            };
            for i in b.first..b.end {
                let w = pose * self.shapes[i].local;
                self.world[i] = to_parry(&w);
                self.centres[i] = w.translation.vector;
            }
        }
    }

    /// Places every body at world configuration `q` for [`Self::pair_within`].
    pub(crate) fn set_config(&mut self, q: &[f64]) {
        self.checks += 1;
        self.update(q);
    }

    /// True when the bodies of checked pair `p` (index in [`CollisionWorld::pairs`] order)
    /// intersect or come within `margin` at the configuration of the last
    /// [`Self::set_config`].
    pub(crate) fn pair_within(&self, p: usize, margin: f64) -> bool {
        let (a, b) = self.pairs[p];
        let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
        (ba.first..ba.end).any(|i| {
            (bb.first..bb.end).any(|j| {
                self.sphere_gap(i, j) <= margin
                    && (self.shapes_intersect(i, j) || self.shape_distance(i, j) <= margin)
            })
        })
    }

    /// Lower bound on the distance between shapes `i` and `j` from their bounding spheres.
    #[inline]
    fn sphere_gap(&self, i: usize, j: usize) -> f64 {
        (self.centres[i] - self.centres[j]).norm() - self.shapes[i].radius - self.shapes[j].radius
    }

    /// True when shapes `i` and `j` intersect (unsupported pairs count as intersecting). A solid
    /// mesh is its surface and inside: a shape wholly inside it (or holding it) intersects.
    #[inline]
    fn shapes_intersect(&self, i: usize, j: usize) -> bool {
        if self.sphere_gap(i, j) > 0.0 {
            return false;
        }
        query::intersection_test(
            &self.world[i],
            self.shapes[i].shape.as_ref(),
            &self.world[j],
            self.shapes[j].shape.as_ref(),
        )
        .map(|r| r.intersecting)
        .unwrap_or(true)
            || self.nested(i, j)
    }

    /// With a solid mesh among shapes `i` and `j` whose surfaces do not meet: whether one lies
    /// inside the other (tested at one point of it, its witness).
    fn nested(&self, i: usize, j: usize) -> bool {
        let (si, sj) = (&self.shapes[i], &self.shapes[j]);
        if si.solid.is_none() && sj.solid.is_none() {
            return false;
        }
        let inside = |outer: usize, inner: usize| {
            let (o, n) = (&self.shapes[outer], &self.shapes[inner]);
            let p = self.world[inner] * n.witness;
            match &o.solid {
                Some(solid) => {
                    let l = self.world[outer].inverse_transform_point(p);
                    solid.contains(&Vector3::new(l.x, l.y, l.z))
                }
                None => o.shape.contains_point(&self.world[outer], p),
            }
        };
        inside(i, j) || inside(j, i)
    }

    /// Distance between shapes `i` and `j` (0 when intersecting or unsupported).
    #[inline]
    fn shape_distance(&self, i: usize, j: usize) -> f64 {
        if self.nested(i, j) {
            return 0.0;
        }
        query::distance(
            &self.world[i],
            self.shapes[i].shape.as_ref(),
            &self.world[j],
            self.shapes[j].shape.as_ref(),
        )
        .map(|d| d.distance.max(0.0))
        .unwrap_or(0.0)
    }

    /// True when bodies `a` and `b` intersect.
    fn bodies_intersect(&self, a: usize, b: usize) -> bool {
        let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
        (ba.first..ba.end).any(|i| (bb.first..bb.end).any(|j| self.shapes_intersect(i, j)))
    }

    /// Index of the first colliding pair at the configuration last updated.
    fn first_colliding_pair(&self) -> Option<usize> {
        self.pairs
            .iter()
            .position(|&(a, b)| self.bodies_intersect(a, b))
    }

    /// Minimum distance over all checked pairs at configuration `q` (0 when some pair
    /// intersects, `f64::INFINITY` when the world has no pair to check).
    pub fn clearance(&mut self, q: &[f64]) -> f64 {
        self.closest_pair(q).map_or(f64::INFINITY, |(d, _)| d)
    }

    /// The minimum distance over all checked pairs at `q` and the pair it is measured between
    /// (`None` when the world has no pair to check). The distance is 0 when the pair intersects.
    pub fn closest_pair(&mut self, q: &[f64]) -> Option<(f64, Contact)> {
        self.checks += 1;
        self.update(q);
        let mut best = f64::INFINITY;
        let mut best_pair = None;
        'pairs: for (p, &(a, b)) in self.pairs.iter().enumerate() {
            let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
            for i in ba.first..ba.end {
                for j in bb.first..bb.end {
                    if best_pair.is_some() && self.sphere_gap(i, j) >= best {
                        continue;
                    }
                    let d = self.shape_distance(i, j);
                    if d < best || best_pair.is_none() {
                        best = d;
                        best_pair = Some(p);
                        if d <= 0.0 {
                            break 'pairs;
                        }
                    }
                }
            }
        }
        best_pair.map(|p| {
            let (a, b) = self.pairs[p];
            (
                best,
                Contact {
                    a: self.names[a].clone(),
                    b: self.names[b].clone(),
                },
            )
        })
    }

    /// True when every checked pair is farther apart than `margin` at `q` (for `margin <= 0`
    /// this is [`CollisionChecker::is_free`]).
    pub fn is_free_with_margin(&mut self, q: &[f64], margin: f64) -> bool {
        if margin <= 0.0 {
            return self.is_free(q);
        }
        self.checks += 1;
        self.update(q);
        for &(a, b) in &self.pairs {
            let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
            for i in ba.first..ba.end {
                for j in bb.first..bb.end {
                    if self.sphere_gap(i, j) > margin {
                        continue;
                    }
                    if self.shape_distance(i, j) <= margin {
                        return false;
                    }
                }
            }
        }
        true
    }
}

impl CollisionChecker for ExactChecker {
    fn is_free(&mut self, q: &[f64]) -> bool {
        self.checks += 1;
        self.update(q);
        self.first_colliding_pair().is_none()
    }

    fn first_contact(&mut self, q: &[f64]) -> Option<Contact> {
        self.checks += 1;
        self.update(q);
        self.first_colliding_pair().map(|p| {
            let (a, b) = self.pairs[p];
            Contact {
                a: self.names[a].clone(),
                b: self.names[b].clone(),
            }
        })
    }

    fn checks(&self) -> u64 {
        self.checks
    }
}
