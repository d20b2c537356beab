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

/// The rotation of URDF roll-pitch-yaw, as `UnitQuaternion::from_euler_angles` computes it, with
/// the fast [`super::sin_cos`] (within a few ulp; gradient ascent in reachability space builds
/// many). Model files keep the library's version, so writing them back is textually stable.
#[inline]
pub fn quat_from_rpy(rpy: [f64; 3]) -> UnitQuaternion<f64> {
    let (sr, cr) = super::sin_cos(0.5 * rpy[0]);
    let (sp, cp) = super::sin_cos(0.5 * rpy[1]);
    let (sy, cy) = super::sin_cos(0.5 * rpy[2]);
    UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quat_from_rpy_is_nalgebras() {
        for i in 0..2000 {
            let f = i as f64;
            let rpy = [
                (f * 0.731).sin() * 4.0,
                (f * 1.113).cos() * 2.0,
                (f * 0.377).sin() * 7.0,
            ];
            let a = quat_from_rpy(rpy);
            let b = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
            assert!((a.coords - b.coords).norm() < 1e-14, "{rpy:?}");
            assert!((a.norm() - 1.0).abs() < 1e-14);
        }
    }
}
