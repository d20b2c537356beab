//! The OpenAPI 3.1 description of the API, generated from the Rust types (utoipa). The checked-in
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
        super::resources::list_robots, super::resources::get_robot, super::resources::put_robot,
        super::resources::delete_robot, super::resources::list_scenes, super::resources::get_scene,
        super::resources::put_scene, super::resources::delete_scene,
        super::queries::fk, super::queries::ik, super::queries::check,
        super::grasp_ik::grasp_ik, super::dual_arm_ik::dual_arm_ik, super::dual_arm_ik::base_placement,
        super::grasp_quality::grasp_quality,
        super::plans::submit, super::plans::list, super::plans::get, super::plans::cancel, super::plans::events,
    ),
    components(schemas(
        ErrorBody, ErrorDetail, PoseBody, PoseOut, Source, RobotSummary, RobotDetail, JointInfo, GroupInfo,
        EndEffectorInfo, RobotUpload, SceneSummary, SceneRobotInfo, FkRequest, FkResponse, LinkPose,
        IkRequest, IkResponse, IkFrame, IkSolver, IkOrder, CheckRequest, CheckResponse, CheckFast,
        SceneRobotConfig, PlanRequest, JointSpacePlan, PlanRobot, CollisionSweep, ReachPlan, GraspPlannerName, HandRef, RegraspPlan, KitchenTaskPlan, BimanualPlan, Job, JobState, JobList,
        JobSummary, Health,
        GraspIkRequest, GraspIkResponse, DualArmIkRequest, BasePlacementRequest, RegionJson, TwoHandIkResponse,
        GraspContact, GraspQualityRequest, GraspQualityResponse, GraspQualityScore,
    )),
    modifiers(&BearerAuth),
    security(("bearer" = [])),
    tags(
        (name = "resources", description = "robots (URDF + SRDF) and scenes"),
        (name = "queries", description = "synchronous FK, IK and collision checks"),
        (name = "plans", description = "asynchronous planning jobs"),
        (name = "operations", description = "health, readiness, metrics"),
    )
)]
pub struct ApiDoc;

/// The spec as pretty JSON with a trailing newline (the form of `api/openapi.json`).
pub fn openapi_json() -> String {
    let mut s = ApiDoc::openapi()
        .to_pretty_json()
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    s.push('\n');
    s
}
