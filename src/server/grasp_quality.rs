//! `POST /v1/grasp-quality`: force closure, wrench rank and the Ferrari–Canny ε (L1 grasp wrench
//! space, [`crate::grasp`]) of given contacts and/or of a scene object's grasps. A synchronous
//! query: the scene lookup happens on the async side, validation and the computation on the CPU
//! pool.

use std::sync::Arc;
use std::time::Instant;

use axum::extract::State;
use axum::Json;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::grasp::{
    grasp_quality as quality_of, score_object_grasps, Contact, GraspError, GraspQuality,
    WrenchSpaceSettings, MAX_CONTACTS,
};
use crate::model::{GraspType, Scene};

use super::error::{ApiError, ApiResult, ErrorBody};
use super::extract::ApiJson;
use super::AppState;

/// Most primitive wrenches in one wrench space (contacts × (cone_edges + 2 with soft fingers)),
/// bounding the time and memory of one hull: 64 random contacts with 16 edges (1024 wrenches,
/// 1.7e5 facets) took 2.5 s and 45 MB, with 32 edges (2048 wrenches, 6e5 facets) 9 s and 140 MB.
/// The CLI has no such bound.
pub const MAX_WRENCHES: usize = 1024;

/// A contact of a finger on the object.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GraspContact {
    /// Contact point [x, y, z] in metres.
    pub point: [f64; 3],
    /// Inward surface normal (the direction of the finger force); any non-zero length.
    pub normal: [f64; 3],
}

/// `POST /v1/grasp-quality`: give `contacts` (with `centre`), or `scene` + `object` (its grasps
/// are scored), or both (the contacts are then in the object frame and share the object's centre
/// and λ, so their ε compares with the grasps').
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GraspQualityRequest {
    /// Contacts to score (at most 64, and at most 1024 primitive wrenches: contacts ×
    /// (cone_edges + 2 with soft fingers)).
    #[serde(default)]
    pub contacts: Vec<GraspContact>,
    /// Centre of mass of the object, same frame as the contacts. Required without `scene` +
    /// `object`; with them the default is the object's centre of mass (uniform density).
    #[serde(default)]
    pub centre: Option<[f64; 3]>,
    /// Scene of `object`.
    #[serde(default)]
    pub scene: Option<String>,
    /// Object of `scene` whose grasps are scored (their stored contacts).
    #[serde(default)]
    pub object: Option<String>,
    /// Only these grasps of the object, by name (default: all).
    #[serde(default)]
    pub grasps: Option<Vec<String>>,
    /// Coulomb friction coefficient μ > 0 (default 0.5).
    #[serde(default)]
    pub mu: Option<f64>,
    /// Edges of the linearised friction cone, 3..=32 (default 8).
    #[serde(default)]
    pub cone_edges: Option<u32>,
    /// Torque scale λ in 1/m. Default: 1 / the object's radius about the centre (GraspIt!'s
    /// 1 / max radius) with `scene` + `object`, else 1 / the largest contact distance from
    /// `centre`.
    #[serde(default)]
    pub lambda: Option<f64>,
    /// Soft-finger torsional friction γ > 0 in metres: adds the wrenches [0; ±λγn] per contact
    /// (default: point contacts with friction).
    #[serde(default)]
    pub soft_finger: Option<f64>,
}

/// The quality of one grasp of the object.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct GraspQualityScore {
    pub name: String,
    pub end_effector: String,
    /// `power`, `precision` or `pinch`.
    #[serde(rename = "type")]
    #[schema(value_type = String)]
    pub kind: GraspType,
    /// Number of stored contacts (a grasp without contacts has rank 0).
    pub contacts: usize,
    /// The `quality` value stored with the grasp in the scene.
    pub scene_quality: f64,
    pub force_closure: bool,
    pub rank: usize,
    pub epsilon: f64,
    pub wrenches: usize,
    pub facets: usize,
}

/// Answer of `POST /v1/grasp-quality`. The top-level quality fields describe the request's
/// `contacts` and are null when it had none.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct GraspQualityResponse {
    /// The origin of wrench space is strictly inside the hull of the primitive wrenches.
    pub force_closure: Option<bool>,
    /// Rank of the 6×N wrench matrix (< 6: never force closure).
    pub rank: Option<usize>,
    /// Ferrari–Canny ε (L1): distance from the origin to the nearest hull facet; 0 when not
    /// force closure.
    pub epsilon: Option<f64>,
    /// Number of primitive wrenches N.
    pub wrenches: Option<usize>,
    /// Facets of the wrench hull (0 when none was built).
    pub facets: Option<usize>,
    /// Torque scale λ used (with `scene` + `object`: the object's, shared by its grasps and the
    /// contacts; null only for an object of radius 0 without contacts).
    pub lambda: Option<f64>,
    /// Centre of mass used.
    pub centre: [f64; 3],
    /// Upper bound of the object's extent from `centre` (with `scene` + `object`).
    pub radius: Option<f64>,
    pub mu: f64,
    pub cone_edges: u32,
    pub soft_finger: Option<f64>,
    /// One per scored grasp of the object (empty without `scene` + `object`).
    pub grasps: Vec<GraspQualityScore>,
    pub time_us: f64,
}

/// A library error as a 422 naming the request field.
fn invalid(e: &GraspError) -> ApiError {
    ApiError::invalid(e.field(), e.reason())
}

#[utoipa::path(post, path = "/v1/grasp-quality", tag = "queries", request_body = GraspQualityRequest,
    responses((status = 200, body = GraspQualityResponse),
              (status = 400, body = ErrorBody, description = "malformed JSON (NaN and infinities are not JSON)"),
              (status = 404, body = ErrorBody, description = "unknown scene"),
              (status = 422, body = ErrorBody, description = "bad value; `field` names it (`mu`, `cone_edges`, `contacts[2].normal`, …)")))]
pub async fn grasp_quality(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<GraspQualityRequest>,
) -> ApiResult<Json<GraspQualityResponse>> {
    let entry = match (&req.scene, &req.object) {
        (Some(s), Some(_)) => Some(st.catalog.scene(s, "scene")?),
        (None, None) => None,
        (Some(_), None) => return Err(ApiError::invalid("object", "required with 'scene'")),
        (None, Some(_)) => return Err(ApiError::invalid("scene", "required with 'object'")),
    };
    st.pool
        .run_heavy(move || compute(entry.as_ref().map(|e| e.scene.as_ref()), &req))
        .await
        .map(Json)
}

/// Validates and scores a request (`scene` is the looked-up `req.scene`).
pub fn compute(
    scene: Option<&Scene>,
    req: &GraspQualityRequest,
) -> ApiResult<GraspQualityResponse> {
    let started = Instant::now();
    let cone_edges = req.cone_edges.unwrap_or(8);
    let settings = WrenchSpaceSettings {
        mu: req.mu.unwrap_or(0.5),
        cone_edges: cone_edges as usize,
        lambda: req.lambda,
        soft_finger: req.soft_finger,
    };
    settings.validate().map_err(|e| invalid(&e))?;
    if req.contacts.len() > MAX_CONTACTS {
        return Err(invalid(&GraspError::TooManyContacts {
            count: req.contacts.len(),
        }));
    }
    let per_contact = settings.cone_edges + if settings.soft_finger.is_some() { 2 } else { 0 };
    if req.contacts.len() * per_contact > MAX_WRENCHES {
        return Err(ApiError::invalid(
            "contacts",
            format!(
                "{} contacts × {per_contact} primitive wrenches each is more than \
                 {MAX_WRENCHES} wrenches; use fewer contacts or cone edges",
                req.contacts.len()
            ),
        ));
    }
    let centre_in = req.centre.map(Vector3::from);
    let contacts: Vec<Contact> = req
        .contacts
        .iter()
        .map(|c| Contact::new(Vector3::from(c.point), Vector3::from(c.normal)))
        .collect();
    let mut out = GraspQualityResponse {
        force_closure: None,
        rank: None,
        epsilon: None,
        wrenches: None,
        facets: None,
        lambda: None,
        centre: [0.0; 3],
        radius: None,
        mu: settings.mu,
        cone_edges,
        soft_finger: settings.soft_finger,
        grasps: Vec::new(),
        time_us: 0.0,
    };
    // The settings and centre the request's contacts are scored with.
    let (centre, contact_settings) = match (scene, req.object.as_deref()) {
        (Some(scene), Some(name)) => {
            let object = scene.object(name).ok_or_else(|| {
                let names: Vec<&str> = scene.objects.iter().map(|o| o.body.name.as_str()).collect();
                ApiError::invalid(
                    "object",
                    format!(
                        "scene '{}' has no object '{name}' (objects: {})",
                        scene.name,
                        names.join(", ")
                    ),
                )
            })?;
            let grasps = match &req.grasps {
                Some(names) => names
                    .iter()
                    .enumerate()
                    .map(|(i, n)| {
                        object.grasps.iter().find(|g| &g.name == n).ok_or_else(|| {
                            ApiError::invalid(
                                format!("grasps[{i}]"),
                                format!("object '{name}' has no grasp '{n}'"),
                            )
                        })
                    })
                    .collect::<ApiResult<Vec<_>>>()?,
                None => object.grasps.iter().collect(),
            };
            if let Some(g) = grasps
                .iter()
                .find(|g| g.contacts.len() * per_contact > MAX_WRENCHES)
            {
                return Err(ApiError::invalid(
                    "cone_edges",
                    format!(
                        "grasp '{}' has {} contacts × {per_contact} primitive wrenches each, \
                         more than {MAX_WRENCHES} wrenches; use fewer cone edges",
                        g.name,
                        g.contacts.len()
                    ),
                ));
            }
            let scores = score_object_grasps(object, grasps.iter().copied(), centre_in, &settings)
                .map_err(|e| match e {
                    GraspError::InGrasp { .. } => ApiError::invalid("object", e.to_string()),
                    e => invalid(&e),
                })?;
            out.radius = Some(scores.radius);
            out.grasps = grasps
                .iter()
                .zip(&scores.grasps)
                .map(|(g, q)| GraspQualityScore {
                    name: g.name.clone(),
                    end_effector: g.end_effector.clone(),
                    kind: g.kind,
                    contacts: g.contacts.len(),
                    scene_quality: g.quality,
                    force_closure: q.force_closure,
                    rank: q.rank,
                    epsilon: q.epsilon,
                    wrenches: q.wrenches,
                    facets: q.facets,
                })
                .collect();
            (scores.centre, scores.settings)
        }
        _ => {
            let centre = centre_in.ok_or_else(|| {
                ApiError::invalid(
                    "centre",
                    "required without 'scene' and 'object' (the object's centre of mass)",
                )
            })?;
            if contacts.is_empty() {
                return Err(ApiError::invalid(
                    "contacts",
                    "give at least one contact, or 'scene' and 'object'",
                ));
            }
            (centre, settings)
        }
    };
    out.centre = [centre.x, centre.y, centre.z];
    out.lambda = contact_settings.lambda;
    if !contacts.is_empty() {
        let q: GraspQuality =
            quality_of(&contacts, &centre, &contact_settings).map_err(|e| invalid(&e))?;
        out.force_closure = Some(q.force_closure);
        out.rank = Some(q.rank);
        out.epsilon = Some(q.epsilon);
        out.wrenches = Some(q.wrenches);
        out.facets = Some(q.facets);
        out.lambda = Some(q.lambda);
    }
    out.time_us = started.elapsed().as_secs_f64() * 1e6;
    Ok(out)
}
