//! `POST /v1/grasp-quality`: force closure, wrench rank and the Ferrari–Canny ε (L1 grasp wrench
//! space, [`crate::grasp`]) of given contacts and/or of a scene object's grasps. A synchronous
//! query: the scene lookup happens on the async side, validation and the computation on the CPU
//! pool.

use std::sync::Arc;
use std::time::Instant;

use axum::extract::State;
use axum::Json;
use nalgebra::Vector3;

use crate::grasp::{
    grasp_quality as quality_of, score_object_grasps, Contact, GraspError, GraspQuality,
    WrenchSpaceSettings, MAX_CONTACTS,
};
use crate::model::Scene;

use super::api::grasp_type;
use super::error::{ApiError, ApiResult, ErrorBody};
use super::extract::ApiJson;
use super::AppState;

pub use manyhands_api::{
    GraspContact, GraspQualityRequest, GraspQualityResponse, GraspQualityScore,
};

/// Most primitive wrenches in one wrench space (contacts × (cone_edges + 2 with soft fingers)),
/// bounding the time and memory of one hull: 64 random contacts with 16 edges (1024 wrenches,
/// 1.7e5 facets) took 2.5 s and 45 MB, with 32 edges (2048 wrenches, 6e5 facets) 9 s and 140 MB.
/// The CLI has no such bound.
pub const MAX_WRENCHES: usize = 1024;

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
                    kind: grasp_type(g.kind),
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
