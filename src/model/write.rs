//! Writing a `Robot` back as URDF and SRDF text (collision geometry only; the visual elements
//! are not written, their mesh paths being relative to the folder the URDF was read from).
//! Reading the output gives the same model: see the round-trip tests.

use std::fmt::Write;

use super::{GroupMember, Robot};
use crate::geometry::{quat_to_rpy, Pose, Shape};

fn origin(p: &Pose) -> String {
    let t = p.translation.vector;
    let r = quat_to_rpy(&p.rotation);
    format!(
        "<origin xyz=\"{:e} {:e} {:e}\" rpy=\"{:e} {:e} {:e}\"/>",
        t.x, t.y, t.z, r[0], r[1], r[2]
    )
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// URDF text of the robot. Meshes are written with the path they were read from.
pub fn to_urdf(r: &Robot) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<?xml version=\"1.0\"?>\n<robot name=\"{}\">",
        esc(&r.name)
    );
    for l in &r.links {
        let _ = write!(s, "  <link name=\"{}\">", esc(&l.name));
        for g in &l.collision {
            let geo = match &g.shape {
                Shape::Box { half_extents: h } => {
                    format!(
                        "<box size=\"{:e} {:e} {:e}\"/>",
                        2.0 * h.x,
                        2.0 * h.y,
                        2.0 * h.z
                    )
                }
                Shape::Cylinder {
                    radius,
                    half_length,
                } => {
                    format!(
                        "<cylinder radius=\"{radius:e}\" length=\"{:e}\"/>",
                        2.0 * half_length
                    )
                }
                Shape::Sphere { radius } => format!("<sphere radius=\"{radius:e}\"/>"),
                Shape::Capsule {
                    radius,
                    half_length,
                } => {
                    format!(
                        "<capsule radius=\"{radius:e}\" length=\"{:e}\"/>",
                        2.0 * half_length
                    )
                }
                Shape::Mesh(m) => format!("<mesh filename=\"file://{}\"/>", esc(&m.source)),
            };
            let _ = write!(
                s,
                "<collision>{}<geometry>{geo}</geometry></collision>",
                origin(&g.origin)
            );
        }
        s.push_str("</link>\n");
    }
    for j in &r.joints {
        let l = &j.limits;
        let _ = write!(
            s,
            "  <joint name=\"{}\" type=\"{}\"><parent link=\"{}\"/><child link=\"{}\"/>{}<axis xyz=\"{:e} {:e} {:e}\"/>",
            esc(&j.name),
            j.kind.name(),
            esc(&r.links[j.parent].name),
            esc(&r.links[j.child].name),
            origin(&j.origin),
            j.axis.x,
            j.axis.y,
            j.axis.z
        );
        if j.is_movable() {
            if l.bounded {
                let _ = write!(
                    s,
                    "<limit lower=\"{:e}\" upper=\"{:e}\" velocity=\"{:e}\" effort=\"{:e}\"/>",
                    l.lower, l.upper, l.velocity, l.effort
                );
            } else {
                let _ = write!(
                    s,
                    "<limit velocity=\"{:e}\" effort=\"{:e}\"/>",
                    l.velocity, l.effort
                );
            }
        }
        if let Some(m) = j.mimic {
            let _ = write!(
                s,
                "<mimic joint=\"{}\" multiplier=\"{:e}\" offset=\"{:e}\"/>",
                esc(r.var_name(m.var)),
                m.multiplier,
                m.offset
            );
        }
        s.push_str("</joint>\n");
    }
    s.push_str("</robot>\n");
    s
}

/// SRDF text: groups as they were defined, end effectors, group states and disabled collision
/// pairs.
pub fn to_srdf(r: &Robot) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<?xml version=\"1.0\"?>\n<robot name=\"{}\">",
        esc(&r.name)
    );
    for g in &r.groups {
        let _ = write!(s, "  <group name=\"{}\">", esc(&g.name));
        for m in &g.members {
            let _ = match m {
                GroupMember::Joint(n) => write!(s, "<joint name=\"{}\"/>", esc(n)),
                GroupMember::Link(n) => write!(s, "<link name=\"{}\"/>", esc(n)),
                GroupMember::Chain {
                    base_link,
                    tip_link,
                } => write!(
                    s,
                    "<chain base_link=\"{}\" tip_link=\"{}\"/>",
                    esc(base_link),
                    esc(tip_link)
                ),
                GroupMember::Group(n) => write!(s, "<group name=\"{}\"/>", esc(n)),
            };
        }
        s.push_str("</group>\n");
    }
    for e in &r.end_effectors {
        let _ = write!(
            s,
            "  <end_effector name=\"{}\" parent_link=\"{}\" group=\"{}\"",
            esc(&e.name),
            esc(&r.links[e.parent_link].name),
            esc(&e.group)
        );
        if let Some(pg) = &e.parent_group {
            let _ = write!(s, " parent_group=\"{}\"", esc(pg));
        }
        s.push_str("/>\n");
    }
    for st in &r.group_states {
        let _ = write!(
            s,
            "  <group_state name=\"{}\" group=\"{}\">",
            esc(&st.name),
            esc(&st.group)
        );
        for &(v, x) in &st.values {
            let _ = write!(
                s,
                "<joint name=\"{}\" value=\"{x:e}\"/>",
                esc(r.var_name(v))
            );
        }
        s.push_str("</group_state>\n");
    }
    for (a, b, reason) in &r.disabled_reasons {
        let _ = writeln!(
            s,
            "  <disable_collisions link1=\"{}\" link2=\"{}\" reason=\"{}\"/>",
            esc(&r.links[*a].name),
            esc(&r.links[*b].name),
            esc(reason)
        );
    }
    s.push_str("</robot>\n");
    s
}
