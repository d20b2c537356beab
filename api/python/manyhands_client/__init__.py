"""Client of the manyhands planning server (see api/openapi.json).

Standard library only. ``Client`` is synchronous; ``AsyncClient`` runs the same calls in a thread
(``asyncio.to_thread``) so it can be awaited. Errors raise ``ApiError`` carrying the server's
``{"error": {"code", "message", "field"}}``.
"""

from __future__ import annotations

import asyncio
import json
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass
from typing import Any, Dict, Iterator, List, Optional, Tuple

__all__ = ["ApiError", "WaitTimeout", "Client", "AsyncClient", "Event", "FINAL_STATES", "JOB_KINDS"]

# Both are checked against api/openapi.json (`JobState`, the `kind`s of `PlanRequest`) by
# tests/python_sdk.rs, as is every request body the test suite sends and every answer it gets.
FINAL_STATES = frozenset({"succeeded", "failed", "cancelled", "interrupted"})
JOB_KINDS = ("joint_space", "collision_sweep", "reach", "regrasp", "kitchen_task", "bimanual",
             "multi_robot", "schedule", "multi_arm", "grasp_list", "pick_place")
Json = Dict[str, Any]


def _segment(name: str) -> str:
    """``name`` as one URL path segment (``/``, ``?``, ``#`` … percent-encoded)."""
    return urllib.parse.quote(name, safe="")


class ApiError(Exception):
    """A 4xx/5xx answer: HTTP status, error code, message and the offending field path."""

    def __init__(self, status: int, code: str, message: str, field: Optional[str] = None,
                 retry_after: Optional[float] = None) -> None:
        super().__init__(f"{status} {code}: {message}")
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.retry_after = retry_after


class WaitTimeout(TimeoutError):
    """``wait()`` gave up before the job was final; ``job`` is its latest (non-final) state."""

    def __init__(self, job: Json, timeout: float) -> None:
        super().__init__(f"job {job.get('id')} still {job.get('state')} after {timeout} s")
        self.job = job
        self.timeout = timeout


@dataclass
class Event:
    """One Server-Sent Event of a job: ``state``, ``progress`` or ``end``."""

    event: str
    data: Json


class Client:
    """Synchronous client. ``token`` is sent as ``Authorization: Bearer``."""

    def __init__(self, base_url: str = "http://127.0.0.1:8080", token: Optional[str] = None,
                 timeout: float = 60.0) -> None:
        self.base_url = base_url.rstrip("/")
        self.token = token
        self.timeout = timeout

    # -- plumbing ---------------------------------------------------------------------------
    def _request(self, method: str, path: str, body: Any = None,
                 timeout: Optional[float] = None) -> Tuple[int, Dict[str, str], Any]:
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.base_url + path, data=data, method=method)
        if data is not None:
            req.add_header("Content-Type", "application/json")
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(req, timeout=timeout or self.timeout) as resp:
                raw = resp.read()
                ctype = resp.headers.get("Content-Type", "")
                value = json.loads(raw) if raw and "json" in ctype else raw.decode()
                return resp.status, dict(resp.headers), value
        except urllib.error.HTTPError as e:
            raw = e.read()
            try:
                err = json.loads(raw)["error"]
            except (ValueError, KeyError, TypeError):
                err = {"code": "http_error", "message": raw.decode(errors="replace"), "field": None}
            ra = e.headers.get("Retry-After") if e.headers else None
            raise ApiError(e.code, err.get("code", ""), err.get("message", ""), err.get("field"),
                           float(ra) if ra else None) from None

    def _put_bytes(self, path: str, data: bytes) -> Any:
        """PUT a raw body (``application/octet-stream``); the JSON answer."""
        req = urllib.request.Request(self.base_url + path, data=data, method="PUT")
        req.add_header("Content-Type", "application/octet-stream")
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as resp:
                return json.loads(resp.read())
        except urllib.error.HTTPError as e:
            raw = e.read()
            try:
                err = json.loads(raw)["error"]
            except (ValueError, KeyError, TypeError):
                err = {"code": "http_error", "message": raw.decode(errors="replace"), "field": None}
            raise ApiError(e.code, err.get("code", ""), err.get("message", ""), err.get("field"),
                           None) from None

    def _get(self, path: str, **kw: Any) -> Any:
        return self._request("GET", path, **kw)[2]

    def _post(self, path: str, body: Any) -> Any:
        return self._request("POST", path, body)[2]

    # -- operations -------------------------------------------------------------------------
    def health(self) -> Json:
        return self._get("/healthz")

    def metrics(self) -> str:
        return self._get("/metrics")

    # -- resources --------------------------------------------------------------------------
    def robots(self) -> List[Json]:
        return self._get("/v1/robots")

    def robot(self, name: str) -> Json:
        return self._get(f"/v1/robots/{_segment(name)}")

    def put_robot(self, name: str, urdf: str, srdf: Optional[str] = None,
                  joint_limits: Optional[str] = None) -> Json:
        """PUT /v1/robots/NAME: URDF, optional SRDF and optional joint limits (MoveIt's
        ``joint_limits.yaml`` text: velocity and acceleration limits for the trajectories)."""
        body: Json = {"urdf": urdf, "srdf": srdf}
        if joint_limits is not None:
            body["joint_limits"] = joint_limits
        return self._request("PUT", f"/v1/robots/{_segment(name)}", body)[2]

    def delete_robot(self, name: str) -> None:
        self._request("DELETE", f"/v1/robots/{_segment(name)}")

    def scenes(self) -> List[Json]:
        return self._get("/v1/scenes")

    def scene(self, name: str) -> Json:
        return self._get(f"/v1/scenes/{_segment(name)}")

    def put_scene(self, name: str, scene: Json) -> Json:
        return self._request("PUT", f"/v1/scenes/{_segment(name)}", scene)[2]

    def delete_scene(self, name: str) -> None:
        self._request("DELETE", f"/v1/scenes/{_segment(name)}")

    def meshes(self) -> List[Json]:
        return self._get("/v1/meshes")

    def put_mesh(self, name: str, data: bytes) -> Json:
        """PUT /v1/meshes/NAME: an STL, OBJ or COLLADA file (format by NAME's extension) that
        uploaded scenes name as ``meshes/NAME``; answers its vertex and triangle counts."""
        return self._put_bytes(f"/v1/meshes/{_segment(name)}", data)

    def delete_mesh(self, name: str) -> None:
        self._request("DELETE", f"/v1/meshes/{_segment(name)}")

    def visuals(self, robot: str) -> Json:
        """GET /v1/robots/NAME/visuals: the robot's URDF ``<visual>`` elements (``link``,
        ``index``, ``pose`` in the link frame, ``shape`` or the ``problem`` why it cannot be
        drawn); a mesh's ``shape.url`` serves it as OBJ text (:meth:`visual_mesh`)."""
        return self._get(f"/v1/robots/{_segment(robot)}/visuals")

    def visual_mesh(self, robot: str, link: str, index: int) -> str:
        """GET /v1/robots/NAME/visuals/LINK/INDEX: visual mesh INDEX of LINK as Wavefront OBJ
        text, in the geometry frame with the URDF's scale applied."""
        return self._get(f"/v1/robots/{_segment(robot)}/visuals/{_segment(link)}/{int(index)}")

    # -- queries ----------------------------------------------------------------------------
    def fk(self, robot: str, config: Optional[Dict[str, float]] = None, **kw: Any) -> Json:
        return self._post("/v1/fk", {"robot": robot, "config": config or {}, **kw})

    def ik(self, robot: str, group: str, pose: Json, **kw: Any) -> Json:
        return self._post("/v1/ik", {"robot": robot, "group": group, "pose": pose, **kw})

    def grasp_ik(self, scene: str, robot: str, group: str, obj: str, **kw: Any) -> Json:
        """POST /v1/ik/grasp: randomized IK (hip sampled, arm analytic) for one of ``obj``'s grasps
        where it lies in ``scene``; also ``max_tries``, ``psi_samples``, ``seed``, ``reachability``."""
        body = {"scene": scene, "robot": robot, "group": group, "object": obj, **kw}
        return self._post("/v1/ik/grasp", body)

    def dual_arm_ik(self, scene: str, robot: str, obj: str, region: Json, **kw: Any) -> Json:
        """POST /v1/ik/dual-arm: hip and both arms holding ``obj`` with two hands, its origin
        inside ``region`` (``{"min": [x, y, z], "max": [x, y, z]}``, world frame); also ``held``
        (a left grasp the object is already held by), ``left_group``, ``right_group``,
        ``reachability``, ``max_tries``, ``psi_samples``, ``seed``."""
        body = {"scene": scene, "robot": robot, "object": obj, "region": region, **kw}
        return self._post("/v1/ik/dual-arm", body)

    def base_placement_ik(self, scene: str, robot: str, obj: str, **kw: Any) -> Json:
        """POST /v1/ik/base-placement: platform, hip and both arms grasping ``obj`` where it lies
        (IkDualArm, bimanual inverse reachability); also ``radius``, ``cell``, ``yaw_bins``,
        ``left_group``, ``right_group``, ``max_tries``, ``psi_samples``, ``seed``."""
        body = {"scene": scene, "robot": robot, "object": obj, **kw}
        return self._post("/v1/ik/base-placement", body)

    def check(self, scene: str, robots: Optional[List[Json]] = None) -> Json:
        return self._post("/v1/check", {"scene": scene, "robots": robots or []})

    def grasp_quality(self, contacts: Optional[List[Json]] = None, **kw: Any) -> Json:
        """POST /v1/grasp-quality: force closure, rank and Ferrari–Canny ε of ``contacts``
        (``[{"point": [x, y, z], "normal": [x, y, z]}]``, inward normals; give ``centre=[x, y, z]``)
        and/or of a scene object's grasps (``scene=..., object=..., grasps=[names]``); also
        ``mu``, ``cone_edges``, ``lambda``, ``soft_finger``."""
        return self._post("/v1/grasp-quality", {"contacts": contacts or [], **kw})

    def time(self, robot: str, waypoints: List[List[float]], **kw: Any) -> Json:
        """POST /v1/trajectories: the time-optimal trajectory of a path of ``robot`` (the shape of
        ROS's JointTrajectory: ``joint_names``, ``points`` with ``positions``, ``velocities``,
        ``accelerations``, ``time_from_start``; ``waypoints`` with their times); also
        ``joint_names`` or ``group``, ``max_velocity`` / ``max_acceleration`` (by joint),
        ``velocity_scaling``, ``acceleration_scaling``, ``sample_period``. Every plan answer has
        the same ``trajectory`` (multi-robot ones: ``trajectories`` by robot)."""
        return self._post("/v1/trajectories", {"robot": robot, "waypoints": waypoints, **kw})

    # -- jobs -------------------------------------------------------------------------------
    def submit(self, request: Json, wait: Optional[float] = None) -> Json:
        """POST /v1/plans; returns the job (final when ``wait`` seconds sufficed)."""
        q = "" if wait is None else f"?wait={wait}"
        t = None if wait is None else self.timeout + wait
        return self._request("POST", "/v1/plans" + q, request, timeout=t)[2]

    def multi_robot(self, scene: str, obj: str, wait: Optional[float] = None, **kw: Any) -> Json:
        """Job kind ``multi_robot``: Multi-Robot-RRT (paper 002 Alg. 3) with phase-space
        scheduling; also ``robots``, ``s_min``, ``mu``, ``cone_edges``, ``lambda``, ``p_ik``,
        ``deterministic``, ``seed``, ``time_limit``, ``sample_period``."""
        return self.submit({"kind": "multi_robot", "scene": scene, "object": obj, **kw}, wait)

    def schedule(self, scene: str, trajectories: List[Json], wait: Optional[float] = None,
                 **kw: Any) -> Json:
        """Job kind ``schedule``: phase-space scheduling (paper 002 §V) of ``trajectories``
        (``[{"robot", "joints", "path"}]``, one per robot); also ``extend``, ``seed``,
        ``time_limit``, ``sample_period``, ``sequential_fallback``."""
        return self.submit({"kind": "schedule", "scene": scene, "trajectories": trajectories,
                            **kw}, wait)

    def multi_arm(self, scene: str, robots: List[Json], wait: Optional[float] = None,
                  **kw: Any) -> Json:
        """Job kind ``multi_arm``: independent arms in one cell, one timed plan on one clock
        (decoupled, prioritized or composite, the method chosen and reported); ``robots`` is
        ``[{"name", "group", "goal" | "goal_pose", "start"?}]``; also ``method``,
        ``shortcut_iterations``, ``seed``, ``time_limit``."""
        return self.submit({"kind": "multi_arm", "scene": scene, "robots": robots, **kw}, wait)

    def job(self, job_id: str) -> Json:
        return self._get(f"/v1/plans/{_segment(job_id)}")

    def jobs_page(self, limit: Optional[int] = None, cursor: Optional[str] = None,
                  state: Optional[str] = None, kind: Optional[str] = None) -> Json:
        """One page of ``GET /v1/plans`` (newest first): ``{"jobs": [...], "next_cursor"?}``."""
        q = {k: v for k, v in (("limit", limit), ("cursor", cursor), ("state", state),
                               ("kind", kind)) if v is not None}
        path = "/v1/plans" + ("?" + urllib.parse.urlencode(q) if q else "")
        return self._get(path)

    def jobs(self, state: Optional[str] = None, kind: Optional[str] = None) -> List[Json]:
        """Every job (newest first), page by page."""
        out: List[Json] = []
        cursor: Optional[str] = None
        while True:
            page = self.jobs_page(limit=1000, cursor=cursor, state=state, kind=kind)
            out.extend(page["jobs"])
            cursor = page.get("next_cursor")
            if not cursor:
                return out

    def cancel(self, job_id: str) -> Json:
        return self._request("DELETE", f"/v1/plans/{_segment(job_id)}")[2]

    def wait(self, job_id: str, timeout: float = 600.0) -> Json:
        """Blocks until the job is final and returns it; raises ``WaitTimeout`` (carrying the
        job as last seen) when it is not final after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            left = max(0.0, deadline - time.monotonic())
            job = self._request("GET", f"/v1/plans/{_segment(job_id)}?wait={min(left, 60.0):.3f}",
                                timeout=self.timeout + 60.0)[2]
            if job["state"] in FINAL_STATES:
                return job
            if left <= 0.0:
                raise WaitTimeout(job, timeout)

    def events(self, job_id: str) -> Iterator[Event]:
        """Iterates the job's Server-Sent Events until the ``end`` event."""
        req = urllib.request.Request(f"{self.base_url}/v1/plans/{_segment(job_id)}/events")
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        try:
            resp = urllib.request.urlopen(req, timeout=self.timeout)
        except urllib.error.HTTPError as e:
            raise ApiError(e.code, "http_error", e.reason) from None
        with resp:
            name, data = "message", []
            for raw in resp:
                line = raw.decode().rstrip("\r\n")
                if line.startswith("event:"):
                    name = line[6:].strip()
                elif line.startswith("data:"):
                    data.append(line[5:].lstrip())
                elif line == "" and data:
                    ev = Event(name, json.loads("\n".join(data)))
                    yield ev
                    if ev.event == "end":
                        return
                    name, data = "message", []


class AsyncClient:
    """The same API as ``Client``, awaitable (each call runs in a worker thread)."""

    def __init__(self, *args: Any, **kw: Any) -> None:
        self.sync = Client(*args, **kw)

    def __getattr__(self, name: str) -> Any:
        fn = getattr(self.sync, name)
        if name == "events" or not callable(fn):
            return fn

        async def call(*args: Any, **kw: Any) -> Any:
            return await asyncio.to_thread(fn, *args, **kw)

        return call

    async def events(self, job_id: str):  # type: ignore[override]
        """Async iteration of the job's events."""
        it = self.sync.events(job_id)
        while True:
            ev = await asyncio.to_thread(next, it, None)
            if ev is None:
                return
            yield ev
