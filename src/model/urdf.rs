//! URDF reader (links, joints, limits, mimic, collision geometry, visual geometry). Visual
//! elements are read leniently: one that cannot be read is kept as [`VisualGeometry::Invalid`]
//! with its reason and never stops the robot from loading, and visual mesh files are only
//! located here (a viewer reads them), so collision behaviour is that of the collision elements
//! alone.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Unit, Vector3};
use roxmltree::{Document, Node};

use super::robot::{Joint, JointKind, Limits, Link, Mimic, Robot, Visual, VisualGeometry};
use super::ModelError;
use crate::geometry::{iso_from_rpy, Geometry, Mesh, Pose, Shape};

struct Ctx<'a> {
    file: &'a str,
    base_dir: &'a Path,
}

impl Ctx<'_> {
    fn err(&self, element: impl Into<String>, reason: impl Into<String>) -> ModelError {
        ModelError::invalid(self.file, element, reason)
    }
}

struct RawJoint {
    name: String,
    kind: JointKind,
    parent: String,
    child: String,
    origin: Pose,
    axis: Unit<Vector3<f64>>,
    limits: Limits,
    mimic: Option<(String, f64, f64)>,
}

/// Parses URDF text into a robot with links in topological order.
pub(crate) fn parse(text: &str, file: &str, base_dir: &Path) -> Result<Robot, ModelError> {
    let doc = Document::parse(text).map_err(|e| ModelError::Syntax {
        file: file.to_string(),
        reason: e.to_string(),
    })?;
    let ctx = Ctx { file, base_dir };
    let root = doc.root_element();
    if root.tag_name().name() != "robot" {
        return Err(ctx.err(
            format!("<{}>", root.tag_name().name()),
            "the root element must be <robot>",
        ));
    }
    let name = root.attribute("name").unwrap_or("robot").to_string();

    let mut links: Vec<Link> = Vec::new();
    let mut link_names: HashMap<String, usize> = HashMap::new();
    let mut raw_joints: Vec<RawJoint> = Vec::new();
    for node in root.children().filter(|n| n.is_element()) {
        match node.tag_name().name() {
            "link" => {
                let link = parse_link(&ctx, node)?;
                if link_names.insert(link.name.clone(), links.len()).is_some() {
                    return Err(ctx.err(
                        format!("<link name=\"{}\">", link.name),
                        "duplicate link name",
                    ));
                }
                links.push(link);
            }
            "joint" => raw_joints.push(parse_joint(&ctx, node)?),
            // Materials, transmissions, gazebo tags and other extensions carry nothing a planner uses.
            _ => {}
        }
    }
    if links.is_empty() {
        return Err(ctx.err("<robot>", "no <link> elements"));
    }

    // Build the tree: every link has at most one parent joint, exactly one root, no cycles.
    let mut parent_of: Vec<Option<usize>> = vec![None; links.len()];
    let mut seen_joint: HashMap<&str, ()> = HashMap::new();
    for (ji, j) in raw_joints.iter().enumerate() {
        let el = format!("<joint name=\"{}\">", j.name);
        if seen_joint.insert(&j.name, ()).is_some() {
            return Err(ctx.err(el, "duplicate joint name"));
        }
        let p = *link_names.get(&j.parent).ok_or_else(|| {
            ctx.err(
                format!("{el}/<parent>"),
                format!("unknown link '{}'", j.parent),
            )
        })?;
        let c = *link_names.get(&j.child).ok_or_else(|| {
            ctx.err(
                format!("{el}/<child>"),
                format!("unknown link '{}'", j.child),
            )
        })?;
        if p == c {
            return Err(ctx.err(el, "parent and child are the same link (cycle)"));
        }
        if let Some(prev) = parent_of[c] {
            return Err(ctx.err(
                el,
                format!(
                    "link '{}' already has parent joint '{}' (a link may have one parent; cycle or duplicate)",
                    j.child, raw_joints[prev].name
                ),
            ));
        }
        parent_of[c] = Some(ji);
    }
    let roots: Vec<usize> = (0..links.len())
        .filter(|&l| parent_of[l].is_none())
        .collect();
    if roots.len() != 1 {
        let names: Vec<&str> = roots.iter().map(|&l| links[l].name.as_str()).collect();
        let reason = if roots.is_empty() {
            "no root link: the joints form a cycle".to_string()
        } else {
            format!(
                "the links form {} separate trees (roots: {}); connect them with joints",
                roots.len(),
                names.join(", ")
            )
        };
        return Err(ctx.err("<robot>", reason));
    }
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); links.len()];
    for (ji, j) in raw_joints.iter().enumerate() {
        children[link_names[&j.parent]].push(ji);
    }
    // Depth-first order from the root keeps each chain contiguous.
    let mut order: Vec<usize> = Vec::with_capacity(links.len());
    let mut stack = vec![roots[0]];
    while let Some(l) = stack.pop() {
        order.push(l);
        for &ji in children[l].iter().rev() {
            stack.push(link_names[&raw_joints[ji].child]);
        }
    }
    if order.len() != links.len() {
        let unreachable: Vec<&str> = (0..links.len())
            .filter(|l| !order.contains(l))
            .map(|l| links[l].name.as_str())
            .collect();
        return Err(ctx.err(
            "<robot>",
            format!(
                "cycle in the kinematic tree through links: {}",
                unreachable.join(", ")
            ),
        ));
    }
    let mut new_index = vec![0usize; links.len()];
    for (ni, &oi) in order.iter().enumerate() {
        new_index[oi] = ni;
    }

    let mut new_links: Vec<Link> = Vec::with_capacity(links.len());
    let mut joints: Vec<Joint> = Vec::with_capacity(links.len().saturating_sub(1));
    let mut link_slots: Vec<Option<Link>> = links.into_iter().map(Some).collect();
    let mut joint_slots: Vec<Option<RawJoint>> = raw_joints.into_iter().map(Some).collect();
    let mut vars = Vec::new();
    let mut mimics: Vec<(usize, String, f64, f64)> = Vec::new();
    for (ni, &oi) in order.iter().enumerate() {
        let mut link = link_slots[oi]
            .take()
            .ok_or_else(|| ctx.err("<robot>", "internal: link order"))?;
        if ni > 0 {
            let ji = parent_of[oi].ok_or_else(|| ctx.err("<robot>", "internal: parent"))?;
            let rj = joint_slots[ji]
                .take()
                .ok_or_else(|| ctx.err("<robot>", "internal: joint"))?;
            let var = if rj.kind != JointKind::Fixed && rj.mimic.is_none() {
                vars.push(joints.len());
                Some(vars.len() - 1)
            } else {
                None
            };
            if let Some((m, mul, off)) = rj.mimic.clone() {
                mimics.push((joints.len(), m, mul, off));
            }
            link.parent_joint = Some(joints.len());
            joints.push(Joint {
                name: rj.name,
                kind: rj.kind,
                parent: new_index[link_names[&rj.parent]],
                child: ni,
                origin: rj.origin,
                axis: rj.axis,
                limits: rj.limits,
                var,
                mimic: None,
            });
        }
        new_links.push(link);
    }
    for (ji, target, mul, off) in mimics {
        let el = format!("<joint name=\"{}\">/<mimic>", joints[ji].name);
        let t = joints
            .iter()
            .position(|j| j.name == target)
            .ok_or_else(|| ctx.err(&el, format!("unknown joint '{target}'")))?;
        let var = joints[t].var.ok_or_else(|| {
            ctx.err(
                &el,
                format!("joint '{target}' is fixed or itself a mimic joint"),
            )
        })?;
        joints[ji].mimic = Some(Mimic {
            var,
            multiplier: mul,
            offset: off,
        });
    }
    Ok(Robot::new_tree(name, new_links, joints, vars))
}

fn attr_f64(ctx: &Ctx, el: &str, node: Node, name: &str) -> Result<Option<f64>, ModelError> {
    match node.attribute(name) {
        None => Ok(None),
        Some(s) => {
            let v: f64 = s
                .trim()
                .parse()
                .map_err(|_| ctx.err(el, format!("attribute {name}=\"{s}\" is not a number")))?;
            if !v.is_finite() {
                return Err(ctx.err(el, format!("attribute {name}=\"{s}\" is not finite")));
            }
            Ok(Some(v))
        }
    }
}

fn parse_vec3(ctx: &Ctx, el: &str, node: Node, name: &str) -> Result<Option<[f64; 3]>, ModelError> {
    let Some(s) = node.attribute(name) else {
        return Ok(None);
    };
    let parts: Vec<&str> = s.split_whitespace().collect();
    if parts.len() != 3 {
        return Err(ctx.err(el, format!("attribute {name}=\"{s}\" must hold 3 numbers")));
    }
    let mut out = [0.0; 3];
    for (o, p) in out.iter_mut().zip(parts) {
        *o = p
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                ctx.err(
                    el,
                    format!("attribute {name}=\"{s}\": '{p}' is not a finite number"),
                )
            })?;
    }
    Ok(Some(out))
}

fn parse_origin(ctx: &Ctx, el: &str, parent: Node) -> Result<Pose, ModelError> {
    match child(parent, "origin") {
        None => Ok(Pose::identity()),
        Some(o) => {
            let el = format!("{el}/<origin>");
            let xyz = parse_vec3(ctx, &el, o, "xyz")?.unwrap_or([0.0; 3]);
            let rpy = parse_vec3(ctx, &el, o, "rpy")?.unwrap_or([0.0; 3]);
            Ok(iso_from_rpy(xyz, rpy))
        }
    }
}

fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == name)
}

fn parse_link(ctx: &Ctx, node: Node) -> Result<Link, ModelError> {
    let name = node
        .attribute("name")
        .ok_or_else(|| ctx.err("<link>", "missing attribute name"))?
        .to_string();
    let el = format!("<link name=\"{name}\">");
    let mut collision = Vec::new();
    for (i, c) in node
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "collision")
        .enumerate()
    {
        let cel = format!("{el}/<collision>[{i}]");
        let origin = parse_origin(ctx, &cel, c)?;
        let g = child(c, "geometry").ok_or_else(|| ctx.err(&cel, "missing <geometry>"))?;
        let shape = parse_geometry(ctx, &format!("{cel}/<geometry>"), g)?;
        collision.push(Geometry { origin, shape });
    }
    let visual = node
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "visual")
        .enumerate()
        .map(|(i, v)| parse_visual(ctx, &format!("{el}/<visual>[{i}]"), v))
        .collect();
    Ok(Link {
        name,
        parent_joint: None,
        collision,
        visual,
    })
}

/// A `<visual>` element (origin and geometry: box, cylinder, capsule, sphere or mesh with
/// scale). What cannot be read becomes [`VisualGeometry::Invalid`] with the reason; a mesh file
/// is located (as collision meshes are) but not read.
fn parse_visual(ctx: &Ctx, el: &str, v: Node) -> Visual {
    let name = v.attribute("name").map(str::to_string);
    let origin = match parse_origin(ctx, el, v) {
        Ok(o) => o,
        Err(e) => {
            return Visual {
                name,
                origin: Pose::identity(),
                geometry: VisualGeometry::Invalid {
                    reason: e.to_string(),
                },
            }
        }
    };
    let geometry = parse_visual_geometry(ctx, el, v).unwrap_or_else(|e| VisualGeometry::Invalid {
        reason: e.to_string(),
    });
    Visual {
        name,
        origin,
        geometry,
    }
}

fn parse_visual_geometry(ctx: &Ctx, el: &str, v: Node) -> Result<VisualGeometry, ModelError> {
    let g = child(v, "geometry").ok_or_else(|| ctx.err(el, "missing <geometry>"))?;
    let gel = format!("{el}/<geometry>");
    let s = g
        .children()
        .find(|c| c.is_element())
        .ok_or_else(|| ctx.err(&gel, "empty <geometry>"))?;
    let sel = format!("{gel}/<{}>", s.tag_name().name());
    let req = |name: &str| -> Result<f64, ModelError> {
        let x = attr_f64(ctx, &sel, s, name)?
            .ok_or_else(|| ctx.err(&sel, format!("missing attribute {name}")))?;
        if x <= 0.0 {
            return Err(ctx.err(&sel, format!("{name} must be > 0, got {x}")));
        }
        Ok(x)
    };
    Ok(match s.tag_name().name() {
        "box" => {
            let size = parse_vec3(ctx, &sel, s, "size")?
                .ok_or_else(|| ctx.err(&sel, "missing attribute size"))?;
            if size.iter().any(|&x| x <= 0.0) {
                return Err(ctx.err(&sel, "size components must be > 0"));
            }
            VisualGeometry::Box { size }
        }
        "cylinder" => VisualGeometry::Cylinder {
            radius: req("radius")?,
            length: req("length")?,
        },
        "capsule" => VisualGeometry::Capsule {
            radius: req("radius")?,
            length: req("length")?,
        },
        "sphere" => VisualGeometry::Sphere {
            radius: req("radius")?,
        },
        "mesh" => {
            let filename = s
                .attribute("filename")
                .ok_or_else(|| ctx.err(&sel, "missing attribute filename"))?
                .to_string();
            let scale = parse_vec3(ctx, &sel, s, "scale")?.unwrap_or([1.0; 3]);
            if scale.contains(&0.0) {
                return Err(ctx.err(&sel, "scale components must not be 0"));
            }
            let path = resolve_mesh(ctx.base_dir, &filename);
            VisualGeometry::Mesh {
                filename,
                scale,
                path,
            }
        }
        other => {
            return Err(ctx.err(
                &sel,
                format!("unknown geometry '{other}' (box, cylinder, sphere, capsule, mesh)"),
            ))
        }
    })
}

fn parse_geometry(ctx: &Ctx, el: &str, g: Node) -> Result<Shape, ModelError> {
    let s = g
        .children()
        .find(|c| c.is_element())
        .ok_or_else(|| ctx.err(el, "empty <geometry>"))?;
    let sel = format!("{el}/<{}>", s.tag_name().name());
    let req = |name: &str| -> Result<f64, ModelError> {
        let v = attr_f64(ctx, &sel, s, name)?
            .ok_or_else(|| ctx.err(&sel, format!("missing attribute {name}")))?;
        if v <= 0.0 {
            return Err(ctx.err(&sel, format!("{name} must be > 0, got {v}")));
        }
        Ok(v)
    };
    let shape = match s.tag_name().name() {
        "box" => {
            let size = parse_vec3(ctx, &sel, s, "size")?
                .ok_or_else(|| ctx.err(&sel, "missing attribute size"))?;
            if size.iter().any(|&v| v <= 0.0) {
                return Err(ctx.err(&sel, "size components must be > 0"));
            }
            Shape::Box {
                half_extents: Vector3::from(size) * 0.5,
            }
        }
        "cylinder" => Shape::Cylinder {
            radius: req("radius")?,
            half_length: req("length")? * 0.5,
        },
        "capsule" => Shape::Capsule {
            radius: req("radius")?,
            half_length: req("length")? * 0.5,
        },
        "sphere" => Shape::Sphere {
            radius: req("radius")?,
        },
        "mesh" => {
            let fname = s
                .attribute("filename")
                .ok_or_else(|| ctx.err(&sel, "missing attribute filename"))?;
            let scale = parse_vec3(ctx, &sel, s, "scale")?.unwrap_or([1.0; 3]);
            let path = resolve_mesh(ctx.base_dir, fname)
                .ok_or_else(|| ctx.err(&sel, format!("mesh file '{fname}' not found")))?;
            let mesh = Mesh::load(&path, scale).map_err(|r| ctx.err(&sel, r))?;
            Shape::Mesh(Arc::new(mesh))
        }
        other => {
            return Err(ctx.err(
                &sel,
                format!("unknown geometry '{other}' (box, cylinder, sphere, capsule, mesh)"),
            ))
        }
    };
    Ok(shape)
}

/// Resolves `package://pkg/rel`, `file://abs` and relative mesh paths against the URDF folder.
fn resolve_mesh(base_dir: &Path, fname: &str) -> Option<PathBuf> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(rest) = fname.strip_prefix("package://") {
        let rel = rest.split_once('/').map(|(_, r)| r).unwrap_or(rest);
        candidates.push(base_dir.join(rel));
        candidates.push(base_dir.join(rest));
        if let Some(parent) = base_dir.parent() {
            candidates.push(parent.join(rest));
        }
    } else if let Some(abs) = fname.strip_prefix("file://") {
        candidates.push(PathBuf::from(abs));
    } else {
        candidates.push(base_dir.join(fname));
    }
    candidates.into_iter().find(|p| p.is_file())
}

fn parse_joint(ctx: &Ctx, node: Node) -> Result<RawJoint, ModelError> {
    let name = node
        .attribute("name")
        .ok_or_else(|| ctx.err("<joint>", "missing attribute name"))?
        .to_string();
    let el = format!("<joint name=\"{name}\">");
    let ty = node
        .attribute("type")
        .ok_or_else(|| ctx.err(&el, "missing attribute type"))?;
    let kind = match ty {
        "revolute" => JointKind::Revolute,
        "continuous" => JointKind::Continuous,
        "prismatic" => JointKind::Prismatic,
        "fixed" => JointKind::Fixed,
        "planar" | "floating" => {
            return Err(ctx.err(
                &el,
                format!("joint type '{ty}' is not supported: express a planar/holonomic base as two prismatic joints and one revolute joint"),
            ))
        }
        other => return Err(ctx.err(&el, format!("unknown joint type '{other}'"))),
    };
    let link_attr = |tag: &str| -> Result<String, ModelError> {
        child(node, tag)
            .and_then(|n| n.attribute("link"))
            .map(str::to_string)
            .ok_or_else(|| ctx.err(&el, format!("missing <{tag} link=\"…\">")))
    };
    let parent = link_attr("parent")?;
    let child_link = link_attr("child")?;
    let origin = parse_origin(ctx, &el, node)?;
    let axis_v = match child(node, "axis") {
        Some(a) => parse_vec3(ctx, &format!("{el}/<axis>"), a, "xyz")?.unwrap_or([1.0, 0.0, 0.0]),
        None => [1.0, 0.0, 0.0],
    };
    let av = Vector3::from(axis_v);
    if kind != JointKind::Fixed && av.norm() < 1e-9 {
        return Err(ctx.err(format!("{el}/<axis>"), "axis must not be zero"));
    }
    let axis = Unit::new_normalize(if av.norm() < 1e-9 { Vector3::x() } else { av });
    let lel = format!("{el}/<limit>");
    let limit = child(node, "limit");
    let limits = match kind {
        JointKind::Fixed => Limits {
            lower: 0.0,
            upper: 0.0,
            velocity: 0.0,
            effort: 0.0,
            bounded: true,
        },
        JointKind::Continuous => {
            let (velocity, effort) = match limit {
                Some(l) => (
                    attr_f64(ctx, &lel, l, "velocity")?.unwrap_or(f64::INFINITY),
                    attr_f64(ctx, &lel, l, "effort")?.unwrap_or(f64::INFINITY),
                ),
                None => (f64::INFINITY, f64::INFINITY),
            };
            Limits {
                lower: -std::f64::consts::PI,
                upper: std::f64::consts::PI,
                velocity,
                effort,
                bounded: false,
            }
        }
        JointKind::Revolute | JointKind::Prismatic => {
            let l = limit.ok_or_else(|| {
                ctx.err(
                    &el,
                    format!("a {ty} joint needs <limit lower upper velocity effort>"),
                )
            })?;
            let lower = attr_f64(ctx, &lel, l, "lower")?.unwrap_or(0.0);
            let upper = attr_f64(ctx, &lel, l, "upper")?.unwrap_or(0.0);
            let velocity = attr_f64(ctx, &lel, l, "velocity")?
                .ok_or_else(|| ctx.err(&lel, "missing attribute velocity"))?;
            let effort = attr_f64(ctx, &lel, l, "effort")?
                .ok_or_else(|| ctx.err(&lel, "missing attribute effort"))?;
            if lower > upper {
                return Err(ctx.err(&lel, format!("lower {lower} > upper {upper}")));
            }
            if velocity < 0.0 || effort < 0.0 {
                return Err(ctx.err(&lel, "velocity and effort must be ≥ 0"));
            }
            Limits {
                lower,
                upper,
                velocity,
                effort,
                bounded: true,
            }
        }
    };
    let mimic = match child(node, "mimic") {
        None => None,
        Some(m) => {
            let mel = format!("{el}/<mimic>");
            let j = m
                .attribute("joint")
                .ok_or_else(|| ctx.err(&mel, "missing attribute joint"))?
                .to_string();
            let mul = attr_f64(ctx, &mel, m, "multiplier")?.unwrap_or(1.0);
            let off = attr_f64(ctx, &mel, m, "offset")?.unwrap_or(0.0);
            (kind != JointKind::Fixed).then_some((j, mul, off))
        }
    };
    Ok(RawJoint {
        name,
        kind,
        parent,
        child: child_link,
        origin,
        axis,
        limits,
        mimic,
    })
}
