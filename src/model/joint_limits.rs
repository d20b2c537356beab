//! A robot's velocity and acceleration limits in MoveIt's `joint_limits.yaml` format
//! (`moveit_core/robot_model`, `joint_limits_interface`): `robots/NAME.joint_limits.yaml` next to
//! `NAME.urdf`, read with the robot.
//!
//! ```yaml
//! joint_limits:
//!   right_elbow:
//!     has_velocity_limits: true
//!     max_velocity: 2.0
//!     has_acceleration_limits: true
//!     max_acceleration: 4.0
//! ```
//!
//! As in MoveIt, a `max_velocity` with `has_velocity_limits: true` overrides the URDF's
//! `<limit velocity>`. The other keys of MoveIt's format (`has_position_limits`, `min_position`,
//! `max_position`, `has_jerk_limits`, `max_jerk`, `has_effort_limits`, `max_effort` and the
//! top-level `default_velocity_scaling_factor` / `default_acceleration_scaling_factor`) are
//! accepted and not used: positions come from the URDF, jerk is not limited (time-optimal
//! parameterisation of the path under velocity and acceleration limits, see
//! [`crate::trajectory::timing`]), and scaling is given per request. Unknown keys, unknown joints,
//! mimic or fixed joints and limits that are not finite and > 0 are errors naming the element.
//! Parsed with `yaml-rust2` (already the project's YAML reader for the MotionBenchMaker files).

/// Velocity (rad/s or m/s) of a joint whose URDF and joint-limits file give none (0, missing or
/// not finite).
pub const DEFAULT_VELOCITY: f64 = 1.0;

/// Acceleration (rad/s² or m/s²) of a joint without an acceleration limit, as MoveIt's
/// time-parameterisation does (`time_optimal_trajectory_generation.cpp`: "using 1.0").
pub const DEFAULT_ACCELERATION: f64 = 1.0;

use yaml_rust2::{Yaml, YamlLoader};

use super::{ModelError, Robot};

/// Limits of one configuration variable from a joint-limits file (`None`: not given).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VarDynamics {
    pub velocity: Option<f64>,
    pub acceleration: Option<f64>,
}

const KNOWN_KEYS: [&str; 12] = [
    "has_velocity_limits",
    "max_velocity",
    "has_acceleration_limits",
    "max_acceleration",
    "has_position_limits",
    "min_position",
    "max_position",
    "has_jerk_limits",
    "max_jerk",
    "has_effort_limits",
    "max_effort",
    "angle_wraps",
];

fn key_str(y: &Yaml) -> Option<&str> {
    y.as_str()
}

fn number(y: &Yaml) -> Option<f64> {
    match y {
        Yaml::Real(_) => y.as_f64(),
        Yaml::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// Parses `text` (a joint-limits file, `file` naming it in errors) into per-variable limits of
/// `robot` (one entry per configuration variable).
pub fn parse_joint_limits(
    robot: &Robot,
    text: &str,
    file: &str,
) -> Result<Vec<VarDynamics>, ModelError> {
    let docs = YamlLoader::load_from_str(text).map_err(|e| ModelError::Syntax {
        file: file.into(),
        reason: e.to_string(),
    })?;
    let mut out = vec![VarDynamics::default(); robot.dof()];
    let Some(doc) = docs.first() else {
        return Ok(out);
    };
    let Some(top) = doc.as_hash() else {
        return Err(ModelError::invalid(file, "(document)", "not a mapping"));
    };
    for (k, v) in top {
        match key_str(k) {
            Some("joint_limits") => {}
            Some("default_velocity_scaling_factor" | "default_acceleration_scaling_factor") => {
                continue
            }
            other => {
                return Err(ModelError::invalid(
                    file,
                    other.unwrap_or("(key)"),
                    "unknown key (expected joint_limits)",
                ))
            }
        }
        if v.is_null() {
            continue;
        }
        let Some(joints) = v.as_hash() else {
            return Err(ModelError::invalid(file, "joint_limits", "not a mapping"));
        };
        for (jk, jv) in joints {
            let name = key_str(jk).unwrap_or("");
            let el = format!("joint_limits.{name}");
            let var = robot
                .var(name)
                .ok_or_else(|| ModelError::invalid(file, &el, "no such movable joint"))?;
            let Some(entries) = jv.as_hash() else {
                return Err(ModelError::invalid(file, &el, "not a mapping"));
            };
            let get = |key: &str| entries.get(&Yaml::String(key.into()));
            for ek in entries.keys() {
                let k = key_str(ek).unwrap_or("");
                if !KNOWN_KEYS.contains(&k) {
                    return Err(ModelError::invalid(
                        file,
                        format!("{el}.{k}"),
                        "unknown key",
                    ));
                }
            }
            let limit = |has: &str, max: &str| -> Result<Option<f64>, ModelError> {
                let on = match get(has) {
                    None => false,
                    Some(Yaml::Boolean(b)) => *b,
                    Some(_) => {
                        return Err(ModelError::invalid(
                            file,
                            format!("{el}.{has}"),
                            "not true or false",
                        ))
                    }
                };
                if !on {
                    return Ok(None);
                }
                let x = get(max).and_then(number).ok_or_else(|| {
                    ModelError::invalid(file, format!("{el}.{max}"), "missing or not a number")
                })?;
                if !(x.is_finite() && x > 0.0) {
                    return Err(ModelError::invalid(
                        file,
                        format!("{el}.{max}"),
                        format!("{x} is not > 0"),
                    ));
                }
                Ok(Some(x))
            };
            out[var] = VarDynamics {
                velocity: limit("has_velocity_limits", "max_velocity")?,
                acceleration: limit("has_acceleration_limits", "max_acceleration")?,
            };
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn armar() -> Robot {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        Robot::from_files(
            &root.join("robots/armar.urdf"),
            Some(&root.join("robots/armar.srdf")),
        )
        .expect("armar")
    }

    #[test]
    fn moveit_files_parse_and_errors_name_the_element() {
        let r = armar();
        let elbow = r.var("right_elbow").expect("joint");
        // Integers and reals, a limit switched off, MoveIt's other keys accepted.
        let text = "default_velocity_scaling_factor: 0.1\njoint_limits:\n  right_elbow:\n    \
            has_velocity_limits: true\n    max_velocity: 3\n    has_acceleration_limits: false\n    \
            max_acceleration: 0\n    has_jerk_limits: false\n    max_jerk: 0\n";
        let d = parse_joint_limits(&r, text, "f").expect("parse");
        assert_eq!(d[elbow].velocity, Some(3.0));
        assert_eq!(d[elbow].acceleration, None);
        assert_eq!(d.iter().filter(|x| x.velocity.is_some()).count(), 1);
        let mut r2 = r.clone();
        r2.apply_joint_limits(text, "f").expect("apply");
        assert_eq!(r2.velocity_limit(elbow), 3.0);
        assert_eq!(r2.acceleration_limit(elbow), DEFAULT_ACCELERATION);
        for (bad, element) in [
            ("joint_limits:\n  nope: {}\n", "joint_limits.nope"),
            (
                "joint_limits:\n  right_elbow:\n    has_velocity_limits: true\n",
                "joint_limits.right_elbow.max_velocity",
            ),
            (
                "joint_limits:\n  right_elbow:\n    has_velocity_limits: yes please\n",
                "joint_limits.right_elbow.has_velocity_limits",
            ),
            (
                "joint_limits:\n  right_elbow:\n    max_speed: 1\n",
                "joint_limits.right_elbow.max_speed",
            ),
            ("limits: {}\n", "limits"),
        ] {
            match parse_joint_limits(&r, bad, "f") {
                Err(ModelError::Invalid { element: e, .. }) => assert_eq!(e, element, "{bad}"),
                other => panic!("{bad}: {other:?}"),
            }
        }
        assert!(matches!(
            parse_joint_limits(&r, "joint_limits: [", "f"),
            Err(ModelError::Syntax { .. })
        ));
    }
}
