//! Shapes of links, obstacles and objects.

use std::path::Path;
use std::sync::Arc;

use nalgebra::{Point3, Vector3};

use super::solid::{CoverBox, Solid};
use super::Pose;

/// A triangle mesh (collision geometry). A closed, consistently oriented mesh is a [`Solid`]:
/// the exact checker uses its true surface and inside, the fast checkers a box cover of it
/// ([`Mesh::cover`]). Any other mesh is checked as its convex hull (exact) and the box around
/// its vertices (fast), conservative supersets, so a small body inside a closed mesh or in one
/// of its concavities is never missed.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Where the mesh was read from (for messages).
    pub source: String,
    /// Vertices in the shape frame, scale applied.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// The solid it bounds, or why it is not one (see [`Solid::new`]).
    pub solid: Result<Arc<Solid>, String>,
}

impl Mesh {
    /// Reads an STL or OBJ file (COLLADA `.dae` too) and applies a per-axis scale.
    pub fn load(path: &Path, scale: [f64; 3]) -> Result<Mesh, String> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        if !matches!(ext.as_str(), "stl" | "obj" | "dae") {
            return Err(format!(
                "mesh '{}': unsupported format '{ext}' (STL, OBJ and DAE are read)",
                path.display()
            ));
        }
        let scene = mesh_loader::Loader::default()
            .merge_meshes(true)
            .load(path)
            .map_err(|e| format!("mesh '{}': {e}", path.display()))?;
        Mesh::from_loaded(path.display().to_string(), &scene, scale)
    }

    /// Reads STL, OBJ or COLLADA bytes (the format by `name`'s extension and the content)
    /// without touching the file system: an OBJ's `mtllib` is refused rather than read.
    /// `name` names the mesh in messages.
    pub fn parse(bytes: &[u8], name: &str, scale: [f64; 3]) -> Result<Mesh, String> {
        let scene = mesh_loader::Loader::default()
            .merge_meshes(true)
            .load_from_slice_with_reader(bytes, Path::new(name), |p: &Path| {
                Err::<Vec<u8>, _>(std::io::Error::new(
                    std::io::ErrorKind::PermissionDenied,
                    format!(
                        "'{}' is not read (a mesh may not refer to other files)",
                        p.display()
                    ),
                ))
            })
            .map_err(|e| format!("mesh '{name}': {e}"))?;
        Mesh::from_loaded(name.to_string(), &scene, scale)
    }

    fn from_loaded(
        source: String,
        scene: &mesh_loader::Scene,
        scale: [f64; 3],
    ) -> Result<Mesh, String> {
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for m in &scene.meshes {
            let base = vertices.len() as u32;
            for v in &m.vertices {
                vertices.push(Point3::new(
                    v[0] as f64 * scale[0],
                    v[1] as f64 * scale[1],
                    v[2] as f64 * scale[2],
                ));
            }
            for f in &m.faces {
                triangles.push([f[0] + base, f[1] + base, f[2] + base]);
            }
        }
        Mesh::from_triangles(source, vertices, triangles)
    }

    /// The mesh as Wavefront OBJ text (vertices in the shape frame, scale applied).
    pub fn to_obj(&self) -> String {
        use std::fmt::Write;
        let mut out = String::with_capacity(32 * (self.vertices.len() + self.triangles.len()));
        for v in &self.vertices {
            let _ = writeln!(out, "v {} {} {}", v.x, v.y, v.z);
        }
        for t in &self.triangles {
            let _ = writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        out
    }

    /// A mesh from vertices and triangles (`source` names it in messages); the solid is found
    /// once here.
    pub fn from_triangles(
        source: String,
        vertices: Vec<Point3<f64>>,
        triangles: Vec<[u32; 3]>,
    ) -> Result<Mesh, String> {
        if vertices.len() < 4 {
            return Err(format!(
                "mesh '{source}': has {} vertices, a solid needs at least 4",
                vertices.len()
            ));
        }
        if let Some((t, i)) = triangles.iter().enumerate().find_map(|(t, tri)| {
            tri.iter()
                .find(|&&i| i as usize >= vertices.len())
                .map(|&i| (t, i))
        }) {
            return Err(format!(
                "mesh '{source}': triangle {t} uses vertex {i}, it has {}",
                vertices.len()
            ));
        }
        let solid = if vertices
            .iter()
            .all(|v| v.coords.iter().all(|c| c.is_finite()))
        {
            Solid::new(&vertices, &triangles).map(Arc::new)
        } else {
            Err("non-finite vertex".to_string())
        };
        Ok(Mesh {
            source,
            vertices,
            triangles,
            solid,
        })
    }

    /// Boxes `(centre, half extents)` in the shape frame whose union contains the mesh: the
    /// solid's cover, else the box around the vertices.
    pub fn cover(&self) -> Vec<CoverBox> {
        match &self.solid {
            Ok(s) => s.cover.clone(),
            Err(_) => {
                let (lo, hi) = self.aabb();
                vec![((lo + hi) * 0.5, (hi - lo) * 0.5)]
            }
        }
    }

    /// The farthest a point of [`Self::cover`] can be from the mesh's solid (infinite for a
    /// mesh that is not a solid: its box is measured against its convex hull elsewhere).
    pub fn cover_protrusion(&self) -> f64 {
        match &self.solid {
            Ok(s) => s.cover_protrusion(),
            Err(_) => f64::INFINITY,
        }
    }

    /// [`Self::cover`] for a moving body: the solid's coarse cover (at most
    /// [`super::solid::MAX_MOVING_COVER_BOXES`] boxes), else the box around the vertices; and
    /// how far it may protrude beyond the solid (infinite for a mesh that is not a solid).
    pub fn moving_cover(&self) -> (Vec<CoverBox>, f64) {
        match &self.solid {
            Ok(s) => (s.moving_cover.clone(), s.moving_protrusion),
            Err(_) => (self.cover(), f64::INFINITY),
        }
    }

    /// Corners `(lo, hi)` of the axis-aligned box around the vertices (zeros for an empty mesh).
    pub fn aabb(&self) -> (Vector3<f64>, Vector3<f64>) {
        if self.vertices.is_empty() {
            return (Vector3::zeros(), Vector3::zeros());
        }
        self.vertices.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), v| (lo.inf(&v.coords), hi.sup(&v.coords)),
        )
    }

    /// Radius of the smallest origin-centred sphere holding every vertex.
    pub fn max_radius(&self) -> f64 {
        self.vertices
            .iter()
            .map(|v| v.coords.norm())
            .fold(0.0, f64::max)
    }
}

/// A collision shape in its own frame. Cylinders and capsules have their axis along local z and
/// are centred on the origin (the URDF convention).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    Box { half_extents: Vector3<f64> },
    Cylinder { radius: f64, half_length: f64 },
    Sphere { radius: f64 },
    Capsule { radius: f64, half_length: f64 },
    Mesh(Arc<Mesh>),
}

impl Shape {
    /// Short name of the kind ("box", "cylinder", …).
    pub fn kind(&self) -> &'static str {
        match self {
            Shape::Box { .. } => "box",
            Shape::Cylinder { .. } => "cylinder",
            Shape::Sphere { .. } => "sphere",
            Shape::Capsule { .. } => "capsule",
            Shape::Mesh(_) => "mesh",
        }
    }

    /// Radius of a sphere centred on the shape origin that contains the shape.
    pub fn bounding_radius(&self) -> f64 {
        match self {
            Shape::Box { half_extents } => half_extents.norm(),
            Shape::Cylinder {
                radius,
                half_length,
            } => (radius * radius + half_length * half_length).sqrt(),
            Shape::Sphere { radius } => *radius,
            Shape::Capsule {
                radius,
                half_length,
            } => radius + half_length,
            Shape::Mesh(m) => m.max_radius(),
        }
    }

    /// Checks that the dimensions are finite and positive; the error names the parameter.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{name}: must be finite and > 0, got {v}"))
            }
        };
        match self {
            Shape::Box { half_extents } => {
                for (i, v) in half_extents.iter().enumerate() {
                    pos(&format!("half_extents[{i}]"), *v)?;
                }
                Ok(())
            }
            Shape::Cylinder {
                radius,
                half_length,
            }
            | Shape::Capsule {
                radius,
                half_length,
            } => {
                pos("radius", *radius)?;
                pos("length", *half_length)
            }
            Shape::Sphere { radius } => pos("radius", *radius),
            Shape::Mesh(m) => {
                if m.vertices
                    .iter()
                    .all(|v| v.coords.iter().all(|c| c.is_finite()))
                {
                    Ok(())
                } else {
                    Err(format!("mesh '{}': non-finite vertex", m.source))
                }
            }
        }
    }
}

/// A shape placed in a body's frame (a link, an obstacle or an object).
#[derive(Debug, Clone, PartialEq)]
pub struct Geometry {
    /// Pose of the shape in the body frame.
    pub origin: Pose,
    pub shape: Shape,
}
