//! The OpenAPI 3.1 description of the API, generated from the Rust types (utoipa; the bodies are
//! the `manyhands-api` crate's types, built with its `openapi` feature). The checked-in
//! copy is `api/openapi.json`; `tests/server_openapi.rs` fails when it drifts
//! (regenerate with `manyhands serve --print-openapi > api/openapi.json`).

use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

use super::api::*;
use super::error::{ErrorBody, ErrorDetail};

struct BearerAuth;

impl Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        if let Some(c) = openapi.components.as_mut() {
            c.add_security_scheme(
                "bearer",
                SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
            );
        }
    }
}

#[derive(OpenApi)]
#[openapi(
    info(
        title = "manyhands",
        description = "Multi-robot grasp-and-motion planning server. Every 4xx/5xx answer has the body \
            `{\"error\": {\"code\", \"message\", \"field\"}}`; `field` is the path of the offending request \
            field (e.g. `robots[1].start.right_elbow`). With a server token, send `Authorization: Bearer TOKEN`.",
        license(name = "Apache-2.0")
    ),
    paths(
        super::healthz, super::readyz, super::metrics_handler,
        super::resources::list_robots, super::resources::get_robot, super::resources::get_robot_urdf, super::resources::put_robot,
        super::resources::delete_robot, super::resources::list_scenes, super::resources::get_scene,
        super::resources::put_scene, super::resources::delete_scene,
        super::meshes::list_meshes, super::meshes::get_mesh, super::meshes::put_mesh, super::meshes::delete_mesh,
        super::meshes::scene_mesh,
        super::queries::fk, super::queries::ik, super::queries::check, super::trajectories::time_path,
        super::grasp_ik::grasp_ik, super::dual_arm_ik::dual_arm_ik, super::dual_arm_ik::base_placement,
        super::grasp_quality::grasp_quality,
        super::grasp_lists::list_index, super::grasp_lists::get_list,
        super::plans::submit, super::plans::list, super::plans::get, super::plans::cancel, super::plans::events,
    ),
    components(schemas(
        ErrorBody, ErrorDetail, PoseBody, PoseOut, Source, RobotSummary, RobotDetail, JointInfo, GroupInfo,
        EndEffectorInfo, RobotUpload, SceneSummary, SceneRobotInfo, FkRequest, FkResponse, LinkPose,
        IkRequest, IkResponse, IkFrame, IkSolver, IkOrder, CheckRequest, CheckResponse, CheckFast,
        SceneRobotConfig, PlanRequest, JointSpacePlan, super::api::SamplerName, PlanRobot, CollisionSweep, ReachPlan, GraspPlannerName, HandRef, RegraspPlan, KitchenTaskPlan, BimanualPlan, super::api::GraspListPlan, super::api::GraspListParamsBody, super::api::PickPlaceTaskPlan, crate::server::multi_robot::MultiRobotRequest, crate::server::multi_robot::ScheduleRequest, crate::server::multi_robot::ScheduleTrajectory, Job, JobState, JobList,
        JobSummary, Health, super::catalog::MeshSummary,
        GraspIkRequest, GraspIkResponse, DualArmIkRequest, BasePlacementRequest, RegionJson, TwoHandIkResponse,
        GraspContact, GraspQualityRequest, GraspQualityResponse, GraspQualityScore,
        JointTrajectory, TrajectoryPoint, TimedWaypoint, TrajectoryEvent, TrajectoryRequest,
    )),
    modifiers(&BearerAuth),
    security(("bearer" = [])),
    tags(
        (name = "resources", description = "robots (URDF + SRDF), scenes and meshes"),
        (name = "queries", description = "synchronous FK, IK, collision checks and trajectory timing"),
        (name = "plans", description = "asynchronous planning jobs"),
        (name = "operations", description = "health, readiness, metrics"),
    )
)]
pub struct ApiDoc;

/// The spec as pretty JSON with a trailing newline (the form of `api/openapi.json`).
pub fn openapi_json() -> String {
    let spec = ApiDoc::openapi();
    let mut s = match serde_json::to_value(&spec) {
        Ok(mut v) => {
            close_tagged_unions(&mut v);
            serde_json::to_string_pretty(&v)
        }
        Err(e) => Err(e),
    }
    .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    s.push('\n');
    s
}

/// Makes the schemas of internally tagged enums (`PlanRequest`: `#[serde(tag = "kind")]`)
/// satisfiable. utoipa renders each variant as `allOf: [{$ref: Variant}, {required: [kind],
/// properties: {kind}}]`, but the variant's own schema is closed (`additionalProperties: false`,
/// from `deny_unknown_fields`) and has no `kind`, so no body matches. Each such `allOf` becomes
/// one closed object: the variant's properties plus `kind`, required as both declare.
fn close_tagged_unions(spec: &mut serde_json::Value) {
    use serde_json::Value;
    let prefix = "#/components/schemas/";
    let schemas = spec["components"]["schemas"].clone();
    fn merged(all: &[Value], schemas: &Value, prefix: &str) -> Option<Value> {
        let [Value::Object(a), Value::Object(tag)] = all else {
            return None;
        };
        let name = a.get("$ref")?.as_str()?.strip_prefix(prefix)?;
        let mut base = schemas.get(name)?.as_object()?.clone();
        if base.get("additionalProperties") != Some(&Value::Bool(false)) {
            return None;
        }
        let props = base
            .entry("properties")
            .or_insert_with(|| Value::Object(Default::default()));
        for (k, v) in tag.get("properties")?.as_object()? {
            props.as_object_mut()?.insert(k.clone(), v.clone());
        }
        let mut required: Vec<Value> = tag.get("required")?.as_array()?.clone();
        if let Some(r) = base.get("required").and_then(Value::as_array) {
            required.extend(r.iter().cloned());
        }
        base.insert("required".into(), Value::Array(required));
        base.remove("description");
        base.remove("title");
        base.insert("title".into(), Value::String(name.to_string()));
        Some(Value::Object(base))
    }
    let Some(map) = spec["components"]["schemas"].as_object_mut() else {
        return;
    };
    for schema in map.values_mut() {
        let Some(branches) = schema.get_mut("oneOf").and_then(Value::as_array_mut) else {
            continue;
        };
        for b in branches.iter_mut() {
            let all = b.get("allOf").and_then(Value::as_array).cloned();
            if let Some(m) = all.and_then(|all| merged(&all, &schemas, prefix)) {
                *b = m;
            }
        }
    }
}

/// Standalone JSON Schemas (draft 2020-12) of the request bodies, one per operation that takes a
/// JSON body described by a component: `(file name, pretty JSON with a trailing newline)`, e.g.
/// `post-v1-ik-dual-arm.request.schema.json`. Each holds its component and every component it
/// refers to under `$defs`, so it validates on its own (the scene body has its own
/// hand-written `api/scene.schema.json`). Checked in under `api/schemas/`.
pub fn request_schemas() -> Vec<(String, String)> {
    use serde_json::{json, Map, Value};
    let spec: Value = serde_json::from_str(&openapi_json()).unwrap_or(Value::Null);
    let components = spec["components"]["schemas"].clone();
    let prefix = "#/components/schemas/";
    // Names of the components `v` refers to, and `v` with its references moved to `$defs`.
    fn rewrite(v: &Value, prefix: &str, refs: &mut Vec<String>) -> Value {
        match v {
            Value::Object(m) => Value::Object(
                m.iter()
                    .map(|(k, x)| match (k.as_str(), x.as_str()) {
                        ("$ref", Some(r)) if r.starts_with(prefix) => {
                            let name = r[prefix.len()..].to_string();
                            let out = Value::String(format!("#/$defs/{name}"));
                            refs.push(name);
                            (k.clone(), out)
                        }
                        _ => (k.clone(), rewrite(x, prefix, refs)),
                    })
                    .collect(),
            ),
            Value::Array(a) => Value::Array(a.iter().map(|x| rewrite(x, prefix, refs)).collect()),
            x => x.clone(),
        }
    }
    let mut out = Vec::new();
    let Some(paths) = spec["paths"].as_object() else {
        return out;
    };
    for (path, ops) in paths {
        let Some(ops) = ops.as_object() else { continue };
        for (method, op) in ops {
            let r = &op["requestBody"]["content"]["application/json"]["schema"]["$ref"];
            let Some(name) = r.as_str().and_then(|r| r.strip_prefix(prefix)) else {
                continue;
            };
            let mut todo = vec![name.to_string()];
            let mut defs = Map::new();
            while let Some(n) = todo.pop() {
                if defs.contains_key(&n) {
                    continue;
                }
                let mut refs = Vec::new();
                defs.insert(n.clone(), rewrite(&components[&n], prefix, &mut refs));
                todo.extend(refs);
            }
            let slug: String = format!("{method}{path}")
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
                .collect::<String>()
                .split('-')
                .filter(|s| !s.is_empty())
                .collect::<Vec<_>>()
                .join("-");
            let file = format!("{slug}.request.schema.json");
            let doc = json!({
                "$schema": "https://json-schema.org/draft/2020-12/schema",
                "$id": format!("https://manyhands.local/api/schemas/{file}"),
                "title": format!("{} {path} request body", method.to_uppercase()),
                "description": format!("Body of `{} {path}` (component `{name}` of api/openapi.json).", method.to_uppercase()),
                "$ref": format!("#/$defs/{name}"),
                "$defs": Value::Object(defs),
            });
            let mut text = serde_json::to_string_pretty(&doc).unwrap_or_default();
            text.push('\n');
            out.push((file, text));
        }
    }
    out.sort();
    out
}
