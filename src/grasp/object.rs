//! Scoring the grasp set of a scene object ([`crate::model::Object`]) — what `manyhands grasp
//! quality --scene S --object O` and `POST /v1/grasp-quality` with `scene` + `object` do.
//!
//! Every scene grasp carries its contact points with inward unit normals in the object frame
//! (`contacts` of the scene JSON, validated by the scene loader), so nothing is derived from the
//! hand: the contacts are scored as stored. A grasp without contacts scores rank 0, not force
//! closure.
//!
//! All grasps of one object share the centre and the torque scale, so their ε are comparable:
//! the centre is the object's centre of mass (the union of its shapes, uniform density,
//! [`object_centre`]) unless one is given, and λ = 1 / radius (GraspIt!'s 1 / max radius; the
//! radius is the largest distance of the object's surface from that centre, [`object_radius`])
//! unless the settings fix λ. The double-grasp score, the grasp lists and the multi-robot score
//! use the same centre and λ.

use nalgebra::Vector3;

use super::wrench_space::{grasp_quality, Contact, GraspError, GraspQuality, WrenchSpaceSettings};
use super::{object_centre, object_radius};
use crate::model::{ContactPoint, Grasp, Object};

impl From<&ContactPoint> for Contact {
    fn from(c: &ContactPoint) -> Contact {
        Contact::new(Vector3::from(c.point), Vector3::from(c.normal))
    }
}

/// The contacts of a scene grasp (object frame).
pub fn grasp_contacts(g: &Grasp) -> Vec<Contact> {
    g.contacts.iter().map(Contact::from).collect()
}

/// The scores of some grasps of one object.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectGraspScores {
    /// Centre of mass used, object frame.
    pub centre: Vector3<f64>,
    /// Largest distance of the object's surface from `centre` (m).
    pub radius: f64,
    /// The settings used; `lambda` is filled in (1 / radius unless given; `None` only for an
    /// object of radius 0, when each grasp falls back to [`WrenchSpaceSettings::lambda`]'s
    /// default).
    pub settings: WrenchSpaceSettings,
    /// One per grasp, in the order given.
    pub grasps: Vec<GraspQuality>,
}

/// Scores `grasps` (of `object`) with [`grasp_quality`]: centre = `centre` or the object's centre
/// of mass, λ = `settings.lambda` or 1 / the object's radius about that centre.
///
/// Errors: invalid settings or centre (field `mu`, `cone_edges`, `lambda`, `soft_finger`,
/// `centre`), checked before any grasp; a grasp whose contacts cannot be scored (e.g. more than
/// [`super::MAX_CONTACTS`]) is [`GraspError::InGrasp`] naming it.
pub fn score_object_grasps<'a>(
    object: &Object,
    grasps: impl IntoIterator<Item = &'a Grasp>,
    centre: Option<Vector3<f64>>,
    settings: &WrenchSpaceSettings,
) -> Result<ObjectGraspScores, GraspError> {
    settings.validate()?;
    let shapes = &object.body.shapes;
    let centre = match centre {
        Some(c) if c.iter().all(|x| x.is_finite()) => c,
        Some(_) => {
            return Err(GraspError::NonFinite {
                field: "centre".into(),
            })
        }
        None => object_centre(shapes).0,
    };
    let radius = object_radius(shapes, &centre);
    let settings = WrenchSpaceSettings {
        lambda: settings.lambda.or_else(|| {
            (radius > 0.0)
                .then(|| 1.0 / radius)
                .filter(|l| l.is_finite())
        }),
        ..*settings
    };
    let grasps = grasps
        .into_iter()
        .map(|g| {
            grasp_quality(&grasp_contacts(g), &centre, &settings).map_err(|e| GraspError::InGrasp {
                grasp: g.name.clone(),
                error: Box::new(e),
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(ObjectGraspScores {
        centre,
        radius,
        settings,
        grasps,
    })
}
