"""Tests of the Python client against a running server: MANYHANDS_URL (default
http://127.0.0.1:8080). Skipped when no server answers, unless MANYHANDS_REQUIRE_SERVER=1 (as
when `cargo test --test python_sdk` starts a server and runs them).

With MANYHANDS_SDK_RECORD=FILE every request the client sends is appended to FILE as one JSON
line ``{"method", "path", "body", "status", "answer"}``; tests/python_sdk.rs validates each body
and JSON answer against api/openapi.json with an independent JSON Schema validator."""

import asyncio
import json
import os
import pathlib
import sys
import threading
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from manyhands_client import JOB_KINDS, ApiError, AsyncClient, Client, WaitTimeout  # noqa: E402

RECORD = os.environ.get("MANYHANDS_SDK_RECORD")
if RECORD:
    _send = Client._request
    _lock = threading.Lock()

    def _recorded(self, method, path, body=None, timeout=None):  # type: ignore[no-untyped-def]
        def note(status, answer):  # type: ignore[no-untyped-def]
            line = {"method": method, "path": path, "body": body, "status": status,
                    "answer": answer if isinstance(answer, (dict, list)) else None}
            with _lock, open(RECORD, "a", encoding="utf-8") as f:
                f.write(json.dumps(line) + "\n")

        try:
            status, headers, value = _send(self, method, path, body, timeout)
        except ApiError as e:
            note(e.status, {"error": {"code": e.code, "message": e.message, "field": e.field}})
            raise
        note(status, value)
        return status, headers, value

    Client._request = _recorded  # type: ignore[method-assign]

URL = os.environ.get("MANYHANDS_URL", "http://127.0.0.1:8080")
SWEEP = {"kind": "collision_sweep", "scene": "kitchen", "samples": 2000, "time_limit": 5}

MINI_URDF = """<robot name="mini">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0 0 0.25"/><geometry><cylinder radius="0.03" length="0.5"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="1" effort="1"/></joint>
</robot>"""
MINI_SRDF = """<robot name="mini"><group name="all"><joint name="j1"/></group>
  <group_state name="home" group="all"><joint name="j1" value="0.2"/></group_state></robot>"""

# One request per job kind (the README's examples), submitted without waiting and cancelled.
EVERY_KIND = [
    {"kind": "joint_space", "scene": "empty", "robots": [
        {"name": "armar", "group": "right_arm", "goal": {"right_elbow": -1.0, "right_shoulder_1": -0.4}}]},
    {**SWEEP, "samples": 10**9, "time_limit": 30},
    {"kind": "reach", "scene": "kitchen", "robot": "armar", "group": "torso_right_arm",
     "object": "wok", "seed": 3, "planner": "j_plus_rrt"},
    {"kind": "regrasp", "scene": "handoff", "giver": {"robot": "armar_a", "group": "torso_right_arm"},
     "receiver": {"robot": "armar_b", "group": "torso_left_arm"}, "object": "wok"},
    {"kind": "kitchen_task", "scene": "kitchen", "seed": 1},
    {"kind": "bimanual", "scene": "kitchen", "robot": "armar", "object": "table", "p_ik": 0.03},
    {"kind": "multi_robot", "scene": "kitchen_two", "object": "table", "seed": 2, "s_min": 0.1},
    {"kind": "schedule", "scene": "kitchen_two", "trajectories": [
        {"robot": "armar_a", "joints": ["base_x", "base_y"], "path": [[0, -1.2], [0, 2.6]]},
        {"robot": "armar_b", "joints": ["base_x", "base_y"], "path": [[-1.2, -0.7], [1.2, -0.7]]}]},
    {"kind": "multi_arm", "scene": "arms_crossing", "robots": [
        {"name": "armar_a", "group": "right_arm", "goal": {"right_elbow": -0.3}},
        {"name": "armar_b", "group": "left_arm", "goal": {"left_elbow": -0.3}}]},
    {"kind": "grasp_list", "robot": "justin", "hand": "left_hand", "mesh": "statuette",
     "params": {"positions": 8}},
    {"kind": "pick_place", "scene": "pick_place", "robot": "justin", "object": "statuette",
     "pick_hand": "right_hand", "place_hand": "left_hand", "seed": 1},
]


def server_up() -> bool:
    try:
        Client(URL, timeout=2).health()
        return True
    except Exception:
        return False


REQUIRED = os.environ.get("MANYHANDS_REQUIRE_SERVER") == "1"


@unittest.skipUnless(REQUIRED or server_up(), f"no manyhands server at {URL}")
class ClientTest(unittest.TestCase):
    def setUp(self) -> None:
        self.c = Client(URL, token=os.environ.get("MANYHANDS_TOKEN"))

    def test_resources_and_queries(self) -> None:
        self.assertIn("armar", [r["name"] for r in self.c.robots()])
        fk = self.c.fk("armar", {"right_elbow": -1.2}, links=["right_tcp"])
        pose = fk["links"][0]["pose"]
        ik = self.c.ik("armar", "right_arm", {"position": pose["position"], "quat_xyzw": pose["quat_xyzw"]})
        self.assertGreater(ik["solutions_found"], 0)
        self.assertIn("collision", self.c.check("kitchen"))

    def test_grasp_quality(self) -> None:
        cube = [{"point": [0.5, 0, 0], "normal": [-1, 0, 0]}, {"point": [-0.5, 0, 0], "normal": [1, 0, 0]},
                {"point": [0, 0.5, 0], "normal": [0, -1, 0]}, {"point": [0, -0.5, 0], "normal": [0, 1, 0]}]
        q = self.c.grasp_quality(cube, centre=[0, 0, 0], **{"lambda": 1.0})
        self.assertTrue(q["force_closure"])
        self.assertAlmostEqual(q["epsilon"], 0.169650, places=5)
        wok = self.c.grasp_quality(scene="kitchen", object="wok")
        self.assertEqual(len(wok["grasps"]), 25)
        with self.assertRaises(ApiError) as e:
            self.c.grasp_quality(cube, centre=[0, 0, 0], cone_edges=2)
        self.assertEqual(e.exception.status, 422)
        self.assertEqual(e.exception.field, "cone_edges")

    def test_grasp_ik_family(self) -> None:
        g = self.c.grasp_ik("kitchen", "armar", "torso_right_arm", "wok", seed=2)
        self.assertTrue(g["found"])
        self.assertTrue(g["reachability"])
        self.assertEqual(len(g["solution"]), 10)
        region = {"min": [0.3, -0.3, 1.0], "max": [0.6, 0.2, 1.4]}
        d = self.c.dual_arm_ik("kitchen", "armar", "wok", region, held="wok_l_02", seed=2)
        self.assertTrue(d["found"])
        self.assertEqual(d["left_grasp"], "wok_l_02")
        self.assertEqual(len(d["joints"]), 17)
        b = self.c.base_placement_ik("kitchen", "armar", "table", seed=2)
        self.assertTrue(b["found"])
        self.assertEqual(b["joints"][:3], ["base_x", "base_y", "base_yaw"])
        with self.assertRaises(ApiError) as e:
            self.c.dual_arm_ik("kitchen", "armar", "wok", {"min": [1, 0, 0], "max": [0, 0, 0]})
        self.assertEqual(e.exception.status, 422)
        self.assertEqual(e.exception.field, "region")

    def test_trajectories(self) -> None:
        t = self.c.time("armar", [[0.0] * 7, [0.3, 0.0, 0.0, -0.8, 0.0, 0.0, 0.2]],
                        group="right_arm", sample_period=0.05)
        self.assertEqual(len(t["joint_names"]), 7)
        self.assertEqual(t["points"][0]["time_from_start"], 0.0)
        self.assertAlmostEqual(t["points"][-1]["time_from_start"], t["duration"])
        self.assertEqual(t["waypoints"][1]["time_from_start"], t["duration"])
        with self.assertRaises(ApiError) as e:
            self.c.time("armar", [[0.0] * 7], group="right_arm", velocity_scaling=0)
        self.assertEqual((e.exception.status, e.exception.field), (422, "velocity_scaling"))
        job = self.c.submit({"kind": "joint_space", "scene": "empty", "seed": 1,
                             "robots": [{"name": "armar", "group": "right_arm",
                                         "goal": {"right_elbow": -1.0}}]}, wait=30)
        self.assertEqual(job["state"], "succeeded", job)
        traj = job["result"]["trajectory"]
        self.assertEqual(traj["joint_names"], job["result"]["joints"])
        self.assertGreater(len(traj["points"]), 1)

    def test_errors_name_the_field(self) -> None:
        with self.assertRaises(ApiError) as e:
            self.c.fk("armar", {"right_elbow": 4.2})
        self.assertEqual(e.exception.status, 422)
        self.assertEqual(e.exception.field, "config.right_elbow")

    def test_jobs_wait_events_cancel(self) -> None:
        job = self.c.submit(SWEEP)
        done = self.c.wait(job["id"], timeout=30)
        self.assertEqual(done["state"], "succeeded")
        job = self.c.submit({**SWEEP, "samples": 10**9, "time_limit": 0.5})
        events = list(self.c.events(job["id"]))
        self.assertEqual(events[-1].event, "end")
        job = self.c.submit({**SWEEP, "samples": 10**9, "time_limit": 30})
        self.assertEqual(self.c.cancel(job["id"])["state"], "cancelled")
        # The list is paged: every job once, newest first; filters by state.
        everything = self.c.jobs()
        self.assertIn(job["id"], [j["id"] for j in everything])
        page = self.c.jobs_page(limit=1, state="cancelled")
        self.assertEqual(len(page["jobs"]), 1)
        self.assertEqual(page["jobs"][0]["state"], "cancelled")

    def test_wait_timeout_raises_with_the_job(self) -> None:
        job = self.c.submit({**SWEEP, "samples": 10**9, "time_limit": 30})
        with self.assertRaises(WaitTimeout) as e:
            self.c.wait(job["id"], timeout=0.3)
        self.assertIsInstance(e.exception, TimeoutError)
        self.assertEqual(e.exception.job["id"], job["id"])
        self.assertIn(e.exception.job["state"], ("queued", "running"))
        self.assertEqual(self.c.cancel(job["id"])["state"], "cancelled")

    def test_multi_robot_and_schedule(self) -> None:
        job = self.c.multi_robot("kitchen_two", "table", wait=60, seed=2, deterministic=True,
                                 time_limit=60)
        self.assertEqual(job["state"], "succeeded", job)
        r = job["result"]
        self.assertEqual(r["schedule"]["robots"], ["armar_a", "armar_b"])
        trajs = [{"robot": x["name"], "joints": x["variables"], "path": x["waypoints"]}
                 for x in r["robots"]]
        job = self.c.schedule("kitchen_two", trajs, wait=30)
        self.assertEqual(job["state"], "succeeded", job)
        with self.assertRaises(ApiError) as e:
            self.c.schedule("kitchen_two", [{"robot": "ghost", "path": [[0.0]]}])
        self.assertEqual(e.exception.field, "trajectories[0].robot")

    def test_multi_arm(self) -> None:
        scene_file = pathlib.Path(__file__).resolve().parents[3] / "scenes" / "arms_crossing.json"
        scene = json.loads(scene_file.read_text())
        goal = [r["configs"]["goal"] for r in scene["robots"]]
        robots = [{"name": "armar_a", "group": "right_arm", "goal": goal[0]},
                  {"name": "armar_b", "group": "left_arm", "goal": goal[1]}]
        job = self.c.multi_arm("arms_crossing", robots, wait=60, seed=1)
        self.assertEqual(job["state"], "succeeded", job)
        self.assertGreater(job["result"]["makespan"], 0.0)
        with self.assertRaises(ApiError) as e:
            self.c.multi_arm("arms_crossing", [{**robots[0], "group": "tentacle"}, robots[1]])
        self.assertEqual(e.exception.field, "robots[0].group")

    def test_uploads(self) -> None:
        self.assertEqual(self.c.put_robot("mini", MINI_URDF, MINI_SRDF)["name"], "mini")
        self.assertEqual(self.c.robot("mini")["dof"], 1)
        self.c.put_robot("mini", MINI_URDF)  # replaced, without SRDF
        limits = ("joint_limits:\n  j1:\n    has_velocity_limits: true\n    max_velocity: 0.5\n"
                  "    has_acceleration_limits: true\n    max_acceleration: 2\n")
        self.c.put_robot("mini", MINI_URDF, joint_limits=limits)
        # 1 rad at 0.5 rad/s, 2 rad/s²: 0.25 s up, 1.75 s cruise, 0.25 s down.
        self.assertAlmostEqual(self.c.time("mini", [[0.0], [1.0]])["duration"], 2.25)
        self.c.delete_robot("mini")
        with self.assertRaises(ApiError) as e:
            self.c.robot("mini")
        self.assertEqual(e.exception.status, 404)
        scene = self.c.scene("kitchen")
        scene["name"] = "kitchen copy/2"  # a name that must be percent-encoded in the path
        with self.assertRaises(ApiError) as e:
            self.c.put_scene("kitchen copy/2", scene)
        self.assertEqual((e.exception.status, e.exception.field), (422, "name"))
        scene["name"] = "kitchen_copy"
        self.assertEqual(self.c.put_scene("kitchen_copy", scene)["name"], "kitchen_copy")
        self.c.delete_scene("kitchen_copy")
        # A mesh for uploaded scenes (a binary STL tetrahedron), listed, then deleted.
        import struct
        v = [(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)]
        faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
        stl = b"\0" * 80 + struct.pack("<I", len(faces)) + b"".join(
            struct.pack("<12f", 0, 0, 0, *v[a], *v[b], *v[c]) + b"\0\0" for a, b, c in faces)
        self.assertEqual(self.c.put_mesh("tet.stl", stl)["triangles"], 4)
        self.assertIn("tet.stl", [m["name"] for m in self.c.meshes()])
        with self.assertRaises(ApiError) as e:
            self.c.put_mesh("tet.txt", stl)
        self.assertEqual((e.exception.status, e.exception.field), (422, "name"))
        # A robot whose visual is that mesh: its visuals list it with a URL, the mesh is OBJ text.
        vis_urdf = MINI_URDF.replace('<robot name="mini">', '<robot name="mini_vis">').replace(
            '<link name="base">', '<link name="base"><visual><geometry>'
            '<mesh filename="meshes/tet.stl" scale="2 2 2"/></geometry></visual>')
        self.c.put_robot("mini_vis", vis_urdf)
        v = self.c.visuals("mini_vis")
        self.assertEqual(v["robot"], "mini_vis")
        [m] = v["visuals"]
        self.assertEqual((m["link"], m["index"], m["shape"]["type"]), ("base", 0, "mesh"))
        self.assertEqual(m["shape"]["url"], "/v1/robots/mini_vis/visuals/base/0")
        obj = self.c.visual_mesh("mini_vis", "base", 0)
        verts = [line for line in obj.splitlines() if line.startswith("v ")]
        self.assertEqual(len(verts), 4, obj)
        self.assertIn("v 0.2 0 0", verts)
        with self.assertRaises(ApiError) as e:
            self.c.visual_mesh("mini_vis", "base", 1)
        self.assertEqual((e.exception.status, e.exception.field), (404, "index"))
        self.c.delete_robot("mini_vis")
        self.c.delete_mesh("tet.stl")

    def test_every_job_kind_is_accepted(self) -> None:
        self.assertEqual(sorted(r["kind"] for r in EVERY_KIND), sorted(JOB_KINDS))
        for request in EVERY_KIND:
            job = self.c.submit(request)
            self.assertEqual(job["kind"], request["kind"])
            self.assertIn(job["state"], ("queued", "running", "succeeded", "failed"), job)
            self.c.cancel(job["id"])
        for request in EVERY_KIND:
            with self.assertRaises(ApiError) as e:
                self.c.submit({**request, "no_such_field": 1})
            self.assertEqual(e.exception.status, 422, request["kind"])

    def test_async(self) -> None:
        async def go() -> str:
            ac = AsyncClient(URL, token=os.environ.get("MANYHANDS_TOKEN"))
            job = await ac.submit(SWEEP, wait=30)
            names = [ev.event async for ev in ac.events(job["id"])]
            self.assertEqual(names[-1], "end")
            return job["state"]

        self.assertEqual(asyncio.run(go()), "succeeded")


if __name__ == "__main__":
    unittest.main()
