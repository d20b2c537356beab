"""Tests of the Python client against a running server: MANYHANDS_URL (default
http://127.0.0.1:8080). Skipped when no server answers."""

import asyncio
import os
import sys
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from manyhands_client import ApiError, AsyncClient, Client  # noqa: E402

URL = os.environ.get("MANYHANDS_URL", "http://127.0.0.1:8080")
SWEEP = {"kind": "collision_sweep", "scene": "kitchen", "samples": 2000, "time_limit": 5}


def server_up() -> bool:
    try:
        Client(URL, timeout=2).health()
        return True
    except Exception:
        return False


@unittest.skipUnless(server_up(), f"no manyhands server at {URL}")
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
        self.assertIn(self.c.cancel(job["id"])["state"], ("cancelled", "running"))

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
