"""Tests of the Python client against a running server: MANYHANDS_URL (default
http://127.0.0.1:8080). Skipped when no server answers, unless MANYHANDS_REQUIRE_SERVER=1 (as
when `cargo test --test python_sdk` starts a server and runs them)."""

import asyncio
import os
import sys
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from manyhands_client import ApiError, AsyncClient, Client, WaitTimeout  # noqa: E402

URL = os.environ.get("MANYHANDS_URL", "http://127.0.0.1:8080")
SWEEP = {"kind": "collision_sweep", "scene": "kitchen", "samples": 2000, "time_limit": 5}


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
