//! The object of a grasp list (paper 003 §IV-A): its mesh geometry in the object frame, its
//! mass properties ([`super::mass`]: centre of mass of the union of its parts and the largest
//! distance of its surface from it), and the geometric queries the finger search asks of it —
//! intersection, penetration depth and touch, on the true mesh (parry's `TriMesh`) with the
//! winding-number inside test of [`crate::geometry::Solid`] for shapes nested inside it.

use std::sync::Arc;

use nalgebra::{Point3, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::SharedShape;

use super::list::GraspListError;
use super::object_centre;
use super::surface::SurfaceSamples;
use crate::collision::to_parry;
use crate::geometry::{Geometry, Pose, Shape, Solid};

/// One shape of the object: parry shape, pose in the object frame, the solid of a closed mesh,
/// bounding radius about its origin.
#[derive(Clone)]
struct ObjectShape {
    shape: SharedShape,
    pose: Pose,
    parry_pose: parry3d_f64::math::Pose,
    solid: Option<Arc<Solid>>,
    radius: f64,
}

/// The object to grasp: its mesh geometry (object frame), centre of mass and radius.
#[derive(Clone)]
pub struct GraspObject {
    pub name: String,
    pub geometry: Vec<Geometry>,
    /// Centre of mass of the union of the shapes (uniform density) and the largest distance of
    /// the object's surface from it ([`super::mass`]); λ = 1 / radius.
    pub centre: Vector3<f64>,
    pub radius: f64,
    shapes: Vec<ObjectShape>,
}

impl std::fmt::Debug for GraspObject {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GraspObject")
            .field("name", &self.name)
            .field("shapes", &self.geometry.len())
            .finish()
    }
}

impl GraspObject {
    /// An object made of `geometry` (poses in the object frame). Every shape must be a mesh
    /// (the surface is sampled from its triangles); a closed mesh is used as its true solid,
    /// another as its convex hull for collisions.
    pub fn new(name: &str, geometry: Vec<Geometry>) -> Result<GraspObject, GraspListError> {
        if geometry.is_empty() {
            return Err(GraspListError::invalid("object", "has no geometry"));
        }
        let mut shapes = Vec::new();
        for (i, g) in geometry.iter().enumerate() {
            let Shape::Mesh(m) = &g.shape else {
                return Err(GraspListError::invalid(
                    &format!("object.shapes[{i}]"),
                    format!(
                        "a {} (grasp lists sample mesh surfaces only)",
                        g.shape.kind()
                    ),
                ));
            };
            let solid = m.solid.as_ref().ok().cloned();
            let (shape, pose) = match &solid {
                Some(s) => {
                    let pts = s
                        .vertices
                        .iter()
                        .map(|v| parry3d_f64::math::Vector::new(v.x, v.y, v.z))
                        .collect();
                    match SharedShape::trimesh(pts, s.triangles.clone()) {
                        Ok(t) => (t, g.origin),
                        Err(e) => {
                            return Err(GraspListError::invalid(
                                &format!("object.shapes[{i}]"),
                                format!("mesh not usable: {e:?}"),
                            ))
                        }
                    }
                }
                None => crate::collision::parry_shape(g),
            };
            shapes.push(ObjectShape {
                parry_pose: to_parry(&pose),
                shape,
                pose,
                solid,
                radius: m.max_radius(),
            });
        }
        let (centre, radius) = object_centre(&geometry);
        Ok(GraspObject {
            name: name.to_string(),
            geometry,
            centre,
            radius,
            shapes,
        })
    }

    /// The object of one mesh file (OBJ, STL, DAE; metres), named after the file's stem.
    pub fn from_mesh_file(path: &std::path::Path) -> Result<GraspObject, GraspListError> {
        let mesh = crate::geometry::Mesh::load(path, [1.0; 3])
            .map_err(|e| GraspListError::invalid("mesh", e))?;
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("mesh")
            .to_string();
        GraspObject::new(
            &name,
            vec![Geometry {
                origin: Pose::identity(),
                shape: Shape::Mesh(Arc::new(mesh)),
            }],
        )
    }

    /// The object's box (object frame).
    pub fn aabb(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for g in &self.geometry {
            if let Shape::Mesh(m) = &g.shape {
                for v in &m.vertices {
                    let p = (g.origin * v).coords;
                    lo = lo.inf(&p);
                    hi = hi.sup(&p);
                }
            }
        }
        (lo, hi)
    }

    /// The surface points ([`SurfaceSamples`]) of all meshes, spacing `spacing`.
    pub fn sample_surface(
        &self,
        spacing: f64,
        seed: u64,
    ) -> Result<SurfaceSamples, GraspListError> {
        let mut verts = Vec::new();
        let mut tris = Vec::new();
        let mut solid = None;
        for (g, s) in self.geometry.iter().zip(&self.shapes) {
            if let Shape::Mesh(m) = &g.shape {
                let (vs, ts): (&[Point3<f64>], &[[u32; 3]]) = match &s.solid {
                    Some(sol) => (&sol.vertices, &sol.triangles),
                    None => (&m.vertices, &m.triangles),
                };
                let base = verts.len() as u32;
                verts.extend(vs.iter().map(|v| g.origin * v));
                tris.extend(ts.iter().map(|t| t.map(|i| i + base)));
                if self.shapes.len() == 1 && g.origin == Pose::identity() {
                    solid = s.solid.clone();
                }
            }
        }
        SurfaceSamples::new(&verts, &tris, solid.as_deref(), spacing, seed)
            .map_err(|e| GraspListError::invalid("surface_spacing", e))
    }

    /// Whether `shape` at `pose` (object frame) intersects the object (surface or inside).
    pub fn hits(&self, shape: &SharedShape, pose: &Pose, bound: f64) -> bool {
        self.shapes.iter().any(|o| {
            if (pose.translation.vector - o.pose.translation.vector).norm() > bound + o.radius {
                return false;
            }
            let pp = to_parry(pose);
            query::intersection_test(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref())
                .map(|r| r.intersecting)
                .unwrap_or(true)
                || self.nested(o, shape, pose)
        })
    }

    /// How deep `shape` at `pose` enters the object (0 when apart; infinite when it lies inside
    /// or the pair cannot be answered).
    pub fn depth(&self, shape: &SharedShape, pose: &Pose, bound: f64) -> f64 {
        let mut worst = 0.0f64;
        for o in &self.shapes {
            if (pose.translation.vector - o.pose.translation.vector).norm() > bound + o.radius {
                continue;
            }
            let pp = to_parry(pose);
            match query::contact(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref(), 0.0) {
                Ok(Some(c)) => worst = worst.max(-c.dist),
                Ok(None) => {}
                Err(_) => return f64::INFINITY,
            }
            if self.nested(o, shape, pose) {
                return f64::INFINITY;
            }
        }
        worst
    }

    /// Where `shape` at `pose` touches the object within `tol` (distance or depth): the signed
    /// distance (negative: depth), the contact point on the object and the inward normal there.
    pub fn touch(
        &self,
        shape: &SharedShape,
        pose: &Pose,
        tol: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
        let mut best: Option<(f64, Vector3<f64>, Vector3<f64>)> = None;
        let pp = to_parry(pose);
        for o in &self.shapes {
            if let Ok(Some(c)) =
                query::contact(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref(), tol)
            {
                if c.dist.abs() <= tol && best.is_none_or(|b| c.dist < b.0) {
                    let p = Vector3::new(c.point1.x, c.point1.y, c.point1.z);
                    let n = -Vector3::new(c.normal1.x, c.normal1.y, c.normal1.z);
                    if n.norm() > 0.0 {
                        best = Some((c.dist, p, n.normalize()));
                    }
                }
            }
        }
        best
    }

    /// The distance between `shape` at `pose` (object frame) and the object's true geometry
    /// (the mesh surface, and its inside for a closed mesh): 0 when they touch, intersect or the
    /// shape lies inside. A pair parry cannot answer counts as touching (0), so the value never
    /// overstates the clearance.
    pub fn distance(&self, shape: &SharedShape, pose: &Pose) -> f64 {
        let pp = to_parry(pose);
        let mut best = f64::INFINITY;
        for o in &self.shapes {
            let d = query::distance(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref())
                .map_or(0.0, |r| r.distance);
            if d.is_nan() || d <= 0.0 || self.nested(o, shape, pose) {
                return 0.0;
            }
            best = best.min(d);
        }
        best
    }

    fn nested(&self, o: &ObjectShape, shape: &SharedShape, pose: &Pose) -> bool {
        match &o.solid {
            Some(s) => {
                // The shape's origin (primitives are centred on it) inside the solid.
                let l = o.pose.inverse() * Point3::from(pose.translation.vector);
                s.contains(&l.coords)
                    || s.vertices.first().is_some_and(|v| {
                        let w = o.pose * v;
                        let pp = to_parry(pose);
                        shape.contains_point(&pp, parry3d_f64::math::Vector::new(w.x, w.y, w.z))
                    })
            }
            None => false,
        }
    }
}
