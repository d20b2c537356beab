//! Single-grasp lists over HTTP (paper 003 §IV-A, [`crate::grasp::list`]): the job kind
//! `grasp_list` builds one (SSE `progress`: frames done of total) or finds it cached under
//! `<data-dir>/grasps`; `GET /v1/grasp-lists` lists the cached ones and
//! `GET /v1/grasp-lists/{id}` serves one whole. A thin adapter: validation names the request
//! field, the work is the planning core's.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use axum::extract::{Path as AxPath, State};
use axum::Json;
use serde_json::{json, Value};

use crate::grasp::list::workspace_params;
use crate::grasp::list_cache::list_file_name;
use crate::grasp::{
    read_grasp_list, GraspListCache, GraspListError, GraspListParams, GraspObject, Hand,
};

use super::api::{GraspListParamsBody, GraspListPlan};
use super::catalog::{check_name, Catalog};
use super::error::{ApiError, ApiResult, ErrorBody};
use super::kinds::{time_limit, JobContext, JobFailure, JobWork, Prepared};
use super::AppState;

/// The list parameters of a request body (defaults for unset fields), validated.
pub fn list_params(b: Option<&GraspListParamsBody>) -> ApiResult<GraspListParams> {
    let mut p = GraspListParams::default();
    if let Some(b) = b {
        macro_rules! set {
            ($($f:ident),*) => {$( if let Some(v) = &b.$f { p.$f = v.clone(); } )*};
        }
        set!(
            positions,
            orientation_level,
            workspace_steps,
            max_spheres,
            candidates_per_sphere,
            base_steps,
            thumb_contacts,
            contact_tolerance,
            mu,
            cone_edges,
            weights,
            max_grasps,
            seed
        );
        p.surface_spacing = b.surface_spacing;
        p.min_sphere_radius = b.min_sphere_radius;
        p.min_separation = b.min_separation;
        p.fingers = b.fingers.clone();
    }
    p.validate().map_err(|e| list_invalid(&e))?;
    Ok(p)
}

fn list_invalid(e: &GraspListError) -> ApiError {
    let f = e.field();
    let field = if f.is_empty() || f == "hand" || f == "mesh" || f.starts_with("object") {
        f.to_string()
    } else {
        format!("params.{f}")
    };
    ApiError::invalid(field, e.reason())
}

/// The job of `kind: grasp_list`.
struct GraspListWork {
    hand: Hand,
    object: GraspObject,
    params: GraspListParams,
    cache: Arc<GraspListCache>,
}

pub(super) fn prepare_grasp_list(
    r: &GraspListPlan,
    catalog: &Catalog,
    max: f64,
) -> ApiResult<Prepared> {
    let time_limit = time_limit(r.time_limit, max)?;
    let params = list_params(r.params.as_ref())?;
    let robot = catalog.robot(&r.robot, "robot")?.robot.clone();
    if robot.group(&r.hand).is_none() {
        let groups: Vec<&str> = robot.groups.iter().map(|g| g.name.as_str()).collect();
        return Err(ApiError::invalid(
            "hand",
            format!(
                "robot '{}' has no group '{}' (groups: {})",
                robot.name,
                r.hand,
                groups.join(", ")
            ),
        ));
    }
    let hand = Hand::new(
        robot,
        &r.hand,
        params.fingers.as_deref(),
        &workspace_params(&params),
    )
    .map_err(|e| {
        let f = if e.field() == "fingers" {
            "params.fingers"
        } else {
            "hand"
        };
        ApiError::invalid(f, e.to_string())
    })?;
    let object = match (&r.mesh, &r.scene, &r.object) {
        (Some(m), None, None) => {
            check_name(m, "mesh").map_err(|e| e.at("mesh"))?;
            let path = catalog.meshes_dir().join(format!("{m}.obj"));
            if !path.is_file() {
                return Err(ApiError::not_found(
                    "mesh",
                    format!("no built-in mesh '{m}'"),
                ));
            }
            GraspObject::from_mesh_file(&path).map_err(|e| list_invalid(&e))?
        }
        (None, Some(s), Some(o)) => {
            let entry = catalog.scene(s, "scene")?;
            let obj = entry.scene.object(o).ok_or_else(|| {
                ApiError::invalid("object", format!("scene '{s}' has no object '{o}'"))
            })?;
            GraspObject::new(o, obj.body.shapes.clone()).map_err(|e| list_invalid(&e))?
        }
        (None, Some(_), None) => return Err(ApiError::invalid("object", "required with 'scene'")),
        (None, None, Some(_)) => return Err(ApiError::invalid("scene", "required with 'object'")),
        (Some(_), _, _) => {
            return Err(ApiError::invalid(
                "mesh",
                "give 'mesh' or 'scene' with 'object', not both",
            ))
        }
        (None, None, None) => {
            return Err(ApiError::invalid(
                "mesh",
                "missing: give 'mesh' or 'scene' with 'object'",
            ))
        }
    };
    Ok(Prepared {
        work: Box::new(GraspListWork {
            hand,
            object,
            params,
            cache: catalog.grasp_lists(),
        }),
        time_limit,
    })
}

impl JobWork for GraspListWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        // Built on a build thread the job waits for within its time limit and stop flag; a
        // build the time limit left goes on for later jobs (see `super::builds`).
        let done = Arc::new(AtomicUsize::new(0));
        let total = Arc::new(AtomicUsize::new(0));
        let built = Arc::new(AtomicBool::new(false));
        let w = *self;
        let key = format!(
            "grasp list {:x} {}",
            Arc::as_ptr(&w.cache) as usize,
            list_id(&w.hand, &w.object, &w.params)
        );
        let what = format!(
            "the grasp list of hand '{}' of '{}' for '{}'",
            w.hand.group, w.hand.robot.name, w.object.name
        );
        let (cache, hand, object, params) = (
            w.cache.clone(),
            w.hand.clone(),
            w.object.clone(),
            w.params.clone(),
        );
        let (d, t, b) = (done.clone(), total.clone(), built.clone());
        let builds = ctx.builds.clone();
        let report = || {
            let t = total.load(Ordering::Relaxed);
            (t > 0).then(|| {
                json!({"phase": "grasp_frames",
                    "frames_done": done.load(Ordering::Relaxed), "frames": t})
            })
        };
        builds
            .ensure_reporting(
                ctx,
                key,
                &what,
                move |stop| {
                    let progress = |dn: usize, tt: usize| {
                        d.store(dn, Ordering::Relaxed);
                        t.store(tt, Ordering::Relaxed);
                    };
                    match cache.get_or_build(&hand, &object, &params, &progress, &|| stop.stopped())
                    {
                        Ok((_, new)) => {
                            b.store(new, Ordering::Relaxed);
                            Ok(())
                        }
                        Err(GraspListError::Stopped) => Err(None),
                        Err(e) => Err(Some(e.to_string())),
                    }
                },
                &report,
            )
            .map_err(|mut f| {
                if f.code == "failed" {
                    f.code = "invalid_input";
                }
                f
            })?;
        // In memory now: no build.
        let result = w
            .cache
            .get_or_build(&w.hand, &w.object, &w.params, &|_, _| {}, &|| true)
            .map(|(l, _)| (l, built.load(Ordering::Relaxed)));
        match result {
            Ok((list, built)) => {
                let id = list_id(&w.hand, &w.object, &w.params);
                let best: Vec<_> = list.grasps.iter().take(10).collect();
                Ok(json!({
                    "id": id,
                    "built": built,
                    "robot": list.robot,
                    "hand": list.hand,
                    "object": list.object,
                    "fingers": list.fingers,
                    "params": list.params,
                    "stats": list.stats,
                    "grasps": list.grasps.len(),
                    "best": best,
                }))
            }
            Err(e) => Err(JobFailure {
                stopped: false,
                code: "invalid_input",
                message: e.to_string(),
                stats: None,
            }),
        }
    }
}

/// The id of a list: its file name without `.grasps.json`.
fn list_id(hand: &Hand, object: &GraspObject, params: &GraspListParams) -> String {
    list_file_name(hand, object, params)
        .trim_end_matches(".grasps.json")
        .to_string()
}

/// `GET /v1/grasp-lists`: the cached lists (id, robot, hand, object, grasps, parameters).
#[utoipa::path(get, path = "/v1/grasp-lists", tag = "resources",
    responses((status = 200, description = "`{\"lists\": [{id, robot, hand, object, grasps, params, stats}]}`", body = Object)))]
pub async fn list_index(State(st): State<Arc<AppState>>) -> ApiResult<Json<Value>> {
    let dir = st.catalog.grasp_dir().to_path_buf();
    st.pool
        .run_heavy(move || {
            let mut files: Vec<_> = std::fs::read_dir(&dir)
                .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
                .unwrap_or_default();
            files.sort();
            let lists: Vec<Value> = files
                .iter()
                .filter_map(|p| {
                    let name = p.file_name()?.to_str()?;
                    let id = name.strip_suffix(".grasps.json")?;
                    let l = read_grasp_list(p).ok()?;
                    Some(
                        json!({"id": id, "robot": l.robot, "hand": l.hand, "object": l.object,
                        "grasps": l.grasps.len(), "params": l.params, "stats": l.stats}),
                    )
                })
                .collect();
            Ok(json!({ "lists": lists }))
        })
        .await
        .map(Json)
}

/// `GET /v1/grasp-lists/{id}`: one list whole (hand joints, fingers, parameters, hashes,
/// statistics and every grasp: palm pose in the object frame, hand configuration, contacts,
/// ε, quality and its four scores).
#[utoipa::path(get, path = "/v1/grasp-lists/{id}", tag = "resources",
    params(("id" = String, Path, description = "a list id from a `grasp_list` job or `GET /v1/grasp-lists`")),
    responses((status = 200, description = "the list", body = Object),
              (status = 404, body = ErrorBody, description = "no such list"),
              (status = 422, body = ErrorBody, description = "malformed id")))]
pub async fn get_list(
    State(st): State<Arc<AppState>>,
    AxPath(id): AxPath<String>,
) -> ApiResult<Json<Value>> {
    check_name(&id, "grasp list").map_err(|e| e.at("id"))?;
    let path = st.catalog.grasp_dir().join(format!("{id}.grasps.json"));
    st.pool
        .run_heavy(move || {
            if !path.is_file() {
                return Err(ApiError::not_found("id", format!("no grasp list '{id}'")));
            }
            let l = read_grasp_list(&path)
                .map_err(|e| ApiError::not_found("id", format!("grasp list '{id}': {e}")))?;
            serde_json::to_value(&l)
                .map_err(|e| ApiError::not_found("id", format!("grasp list '{id}': {e}")))
        })
        .await
        .map(Json)
}
