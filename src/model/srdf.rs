//! SRDF reader (MoveIt's format): groups (joints, links, chains, subgroups), end effectors,
//! disabled collision pairs and named group states.

use std::collections::{BTreeSet, HashMap};

use roxmltree::{Document, Node};

use super::robot::{EndEffector, Group, GroupMember, GroupState, Robot};
use super::ModelError;

struct RawGroup<'a> {
    name: String,
    node: Node<'a, 'a>,
}

/// Applies SRDF text to a robot read from URDF. Unknown joints, links and groups are errors.
pub(crate) fn apply(robot: &mut Robot, text: &str, file: &str) -> Result<(), ModelError> {
    let doc = Document::parse(text).map_err(|e| ModelError::Syntax {
        file: file.to_string(),
        reason: e.to_string(),
    })?;
    let err = |el: &str, reason: String| ModelError::invalid(file, el, reason);
    let root = doc.root_element();
    if root.tag_name().name() != "robot" {
        return Err(err(
            &format!("<{}>", root.tag_name().name()),
            "the root element must be <robot>".into(),
        ));
    }

    let mut raw_groups: Vec<RawGroup> = Vec::new();
    for node in root.children().filter(|n| n.is_element()) {
        if node.tag_name().name() == "group" {
            let name = node
                .attribute("name")
                .ok_or_else(|| err("<group>", "missing attribute name".into()))?;
            if raw_groups.iter().any(|g| g.name == name) {
                return Err(err(
                    &format!("<group name=\"{name}\">"),
                    "duplicate group name".into(),
                ));
            }
            raw_groups.push(RawGroup {
                name: name.to_string(),
                node,
            });
        }
    }
    let index: HashMap<&str, usize> = raw_groups
        .iter()
        .enumerate()
        .map(|(i, g)| (g.name.as_str(), i))
        .collect();
    let mut resolved: Vec<Option<Group>> = vec![None; raw_groups.len()];
    for gi in 0..raw_groups.len() {
        let mut visiting = Vec::new();
        resolve_group(
            robot,
            &raw_groups,
            &index,
            gi,
            &mut resolved,
            &mut visiting,
            file,
        )?;
    }
    robot.groups = resolved.into_iter().flatten().collect();

    for node in root.children().filter(|n| n.is_element()) {
        match node.tag_name().name() {
            "disable_collisions" => {
                let l1 = node.attribute("link1").unwrap_or("");
                let l2 = node.attribute("link2").unwrap_or("");
                let el = format!("<disable_collisions link1=\"{l1}\" link2=\"{l2}\">");
                let (Some(a), Some(b)) = (robot.link(l1), robot.link(l2)) else {
                    // MoveIt tolerates pairs of links the URDF does not have (SRDFs are shared
                    // between a robot's URDF variants): keep a warning, not an error.
                    let missing = if robot.link(l1).is_none() { l1 } else { l2 };
                    robot.warnings.push(format!(
                        "{file}: {el}: unknown link '{missing}', pair ignored"
                    ));
                    continue;
                };
                let reason = node.attribute("reason").unwrap_or("").to_string();
                robot.disable(a, b, &reason);
            }
            "end_effector" => {
                let name = node.attribute("name").unwrap_or("");
                let el = format!("<end_effector name=\"{name}\">");
                if name.is_empty() {
                    return Err(err(&el, "missing attribute name".into()));
                }
                let pl = node
                    .attribute("parent_link")
                    .ok_or_else(|| err(&el, "missing attribute parent_link".into()))?;
                let parent_link = robot
                    .link(pl)
                    .ok_or_else(|| err(&el, format!("unknown parent_link '{pl}'")))?;
                let group = node
                    .attribute("group")
                    .ok_or_else(|| err(&el, "missing attribute group".into()))?;
                if robot.group(group).is_none() {
                    return Err(err(&el, format!("unknown group '{group}'")));
                }
                let parent_group = node.attribute("parent_group").map(str::to_string);
                if let Some(pg) = &parent_group {
                    if robot.group(pg).is_none() {
                        return Err(err(&el, format!("unknown parent_group '{pg}'")));
                    }
                }
                robot.end_effectors.push(EndEffector {
                    name: name.to_string(),
                    parent_link,
                    group: group.to_string(),
                    parent_group,
                });
            }
            "group_state" => {
                let name = node.attribute("name").unwrap_or("");
                let group = node.attribute("group").unwrap_or("");
                let el = format!("<group_state name=\"{name}\" group=\"{group}\">");
                let g = robot
                    .group(group)
                    .ok_or_else(|| err(&el, format!("unknown group '{group}'")))?;
                let mut values = Vec::new();
                for j in node
                    .children()
                    .filter(|c| c.is_element() && c.tag_name().name() == "joint")
                {
                    let jn = j.attribute("name").unwrap_or("");
                    let jel = format!("{el}/<joint name=\"{jn}\">");
                    let ji = robot
                        .joint(jn)
                        .ok_or_else(|| err(&jel, format!("unknown joint '{jn}'")))?;
                    let Some(v) = robot.joints[ji].var else {
                        // Fixed and mimic joints carry no variable; MoveIt files list them at times.
                        continue;
                    };
                    if !g.vars.contains(&v) {
                        return Err(err(&jel, format!("joint is not in group '{group}'")));
                    }
                    let s = j.attribute("value").unwrap_or("");
                    let x: f64 = s
                        .split_whitespace()
                        .next()
                        .and_then(|t| t.parse().ok())
                        .filter(|x: &f64| x.is_finite())
                        .ok_or_else(|| err(&jel, format!("value \"{s}\" is not a number")))?;
                    let lim = robot.var_limits(v);
                    if !lim.contains(x) {
                        return Err(err(
                            &jel,
                            format!("value {x} outside limit [{}, {}]", lim.lower, lim.upper),
                        ));
                    }
                    values.push((v, x));
                }
                robot.group_states.push(GroupState {
                    name: name.to_string(),
                    group: group.to_string(),
                    values,
                });
            }
            // `group` is read above; virtual and passive joints, sphere approximations and joint
            // properties are MoveIt extras that do not change the model planned with here.
            _ => {}
        }
    }
    Ok(())
}

fn resolve_group(
    robot: &Robot,
    raw: &[RawGroup],
    index: &HashMap<&str, usize>,
    gi: usize,
    resolved: &mut Vec<Option<Group>>,
    visiting: &mut Vec<usize>,
    file: &str,
) -> Result<(), ModelError> {
    if resolved[gi].is_some() {
        return Ok(());
    }
    let name = &raw[gi].name;
    let el = format!("<group name=\"{name}\">");
    let err = |reason: String| ModelError::invalid(file, &el, reason);
    if visiting.contains(&gi) {
        return Err(err("groups include each other (cycle)".into()));
    }
    visiting.push(gi);
    let mut vars: BTreeSet<usize> = BTreeSet::new();
    let mut links: BTreeSet<usize> = BTreeSet::new();
    let mut chains: Vec<(usize, usize)> = Vec::new();
    let mut parts = 0usize;
    let mut members = Vec::new();
    for c in raw[gi].node.children().filter(|c| c.is_element()) {
        parts += 1;
        match c.tag_name().name() {
            "joint" => {
                let jn = c.attribute("name").unwrap_or("");
                let ji = robot
                    .joint(jn)
                    .ok_or_else(|| err(format!("<joint name=\"{jn}\">: unknown joint")))?;
                if let Some(v) = robot.joints[ji].var {
                    vars.insert(v);
                }
                links.insert(robot.joints[ji].child);
                members.push(GroupMember::Joint(jn.to_string()));
            }
            "link" => {
                let ln = c.attribute("name").unwrap_or("");
                let li = robot
                    .link(ln)
                    .ok_or_else(|| err(format!("<link name=\"{ln}\">: unknown link")))?;
                links.insert(li);
                members.push(GroupMember::Link(ln.to_string()));
                if let Some(j) = robot.links[li].parent_joint {
                    if let Some(v) = robot.joints[j].var {
                        vars.insert(v);
                    }
                }
            }
            "chain" => {
                let b = c.attribute("base_link").unwrap_or("");
                let t = c.attribute("tip_link").unwrap_or("");
                let cel = format!("<chain base_link=\"{b}\" tip_link=\"{t}\">");
                let bi = robot
                    .link(b)
                    .ok_or_else(|| err(format!("{cel}: unknown base_link")))?;
                let ti = robot
                    .link(t)
                    .ok_or_else(|| err(format!("{cel}: unknown tip_link")))?;
                let path = robot
                    .link_path(bi, ti)
                    .ok_or_else(|| err(format!("{cel}: tip_link is not below base_link")))?;
                for &l in &path {
                    links.insert(l);
                }
                for &l in &path[1..] {
                    if let Some(j) = robot.links[l].parent_joint {
                        if let Some(v) = robot.joints[j].var {
                            vars.insert(v);
                        }
                    }
                }
                chains.push((bi, ti));
                members.push(GroupMember::Chain {
                    base_link: b.to_string(),
                    tip_link: t.to_string(),
                });
            }
            "group" => {
                let sn = c.attribute("name").unwrap_or("");
                let si = *index
                    .get(sn)
                    .ok_or_else(|| err(format!("<group name=\"{sn}\">: unknown subgroup")))?;
                resolve_group(robot, raw, index, si, resolved, visiting, file)?;
                members.push(GroupMember::Group(sn.to_string()));
                if let Some(sub) = &resolved[si] {
                    vars.extend(sub.vars.iter().copied());
                    links.extend(sub.links.iter().copied());
                    if let Some(ch) = sub.chain {
                        chains.push(ch);
                    } else {
                        chains.push((usize::MAX, usize::MAX));
                    }
                }
            }
            // Passive joints are not planned for.
            "passive_joint" => {}
            other => return Err(err(format!("unknown element <{other}> in a group"))),
        }
    }
    visiting.pop();
    let chain = (chains.len() == 1 && parts == 1 && chains[0].0 != usize::MAX).then(|| chains[0]);
    resolved[gi] = Some(Group {
        members,
        name: name.clone(),
        vars: vars.into_iter().collect(),
        links: links.into_iter().collect(),
        chain,
    });
    Ok(())
}
