//! Rigid poses and their JSON representation.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// A rigid transform in f64 (the kinematics precision).
pub type Pose = Isometry3<f64>;

/// Builds a pose from a translation and URDF roll-pitch-yaw (fixed axes X, then Y, then Z).
pub fn iso_from_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Pose {
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

/// URDF roll-pitch-yaw of a rotation.
pub fn quat_to_rpy(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let (r, p, y) = q.euler_angles();
    [r, p, y]
}

/// JSON form of a pose: `{"position": [x,y,z], "rpy": [r,p,y]}` or with `"quat_xyzw"` instead of
/// `"rpy"`. Both fields are optional (identity). Metres and radians.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseJson {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpy: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quat_xyzw: Option<[f64; 4]>,
}

impl PoseJson {
    /// Converts to an isometry; the error names the offending field.
    pub fn to_pose(&self) -> Result<Pose, String> {
        let p = self.position.unwrap_or([0.0; 3]);
        if p.iter().any(|v| !v.is_finite()) {
            return Err("position: values must be finite".into());
        }
        let rot = match (self.rpy, self.quat_xyzw) {
            (Some(_), Some(_)) => return Err("rpy and quat_xyzw are mutually exclusive".into()),
            (Some(r), None) => {
                if r.iter().any(|v| !v.is_finite()) {
                    return Err("rpy: values must be finite".into());
                }
                UnitQuaternion::from_euler_angles(r[0], r[1], r[2])
            }
            (None, Some(q)) => {
                if q.iter().any(|v| !v.is_finite()) {
                    return Err("quat_xyzw: values must be finite".into());
                }
                let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
                if n.is_nan() || n <= 1e-9 {
                    return Err("quat_xyzw: zero quaternion".into());
                }
                UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
            }
            (None, None) => UnitQuaternion::identity(),
        };
        Ok(Isometry3::from_parts(
            Translation3::from(Vector3::from(p)),
            rot,
        ))
    }

    /// The JSON form of a pose, with position and quaternion.
    pub fn from_pose(p: &Pose) -> Self {
        let q = p.rotation.quaternion();
        PoseJson {
            position: Some(p.translation.vector.into()),
            rpy: None,
            quat_xyzw: Some([q.i, q.j, q.k, q.w]),
        }
    }
}
