#!/usr/bin/env python3
"""Generates tests/data/timing/toppra_fixture.json, the outside reference of tests/timing.rs.

Run once (the test only reads the JSON; CI does not need toppra):

    python3 -m venv /tmp/toppra-venv && /tmp/toppra-venv/bin/pip install toppra
    /tmp/toppra-venv/bin/python tests/data/timing/make_toppra_fixture.py

Random joint-space polylines (seeded) of armar's and justin's groups, with the limits of
robots/NAME.urdf (velocity) and robots/NAME.joint_limits.yaml (acceleration), and of a
Panda-like 7-DoF arm with libfranka's published limits. The path manyhands times is the
polyline itself, at rest at every corner, so toppra (Pham & Pham 2018, the reference
implementation) times each segment as a straight geometric path from rest to rest
(`SplineInterpolator` through the two ends with natural boundary conditions is the straight
line), on a fine grid; the reference duration of a path is the sum.
"""

import importlib.metadata
import json
import os
import xml.etree.ElementTree as ET

import numpy as np
import toppra as ta
import toppra.algorithm as algo
import toppra.constraint as constraint

ROOT = os.path.join(os.path.dirname(__file__), "..", "..", "..")
ta.setup_logging("WARNING")


def urdf_joints(robot):
    """{joint: (lower, upper, velocity)} of the movable joints of robots/ROBOT.urdf."""
    t = ET.parse(os.path.join(ROOT, "robots", robot + ".urdf")).getroot()
    out = {}
    for j in t.findall("joint"):
        if j.get("type") in ("fixed", None) or j.find("mimic") is not None:
            continue
        lim = j.find("limit")
        lo = float(lim.get("lower", "-3.14159"))
        hi = float(lim.get("upper", "3.14159"))
        if j.get("type") == "continuous":
            lo, hi = -3.14159, 3.14159
        out[j.get("name")] = (lo, hi, float(lim.get("velocity", "1")))
    return out


def yaml_acc(robot):
    """max_acceleration by joint from robots/ROBOT.joint_limits.yaml (the simple form shipped)."""
    acc, joint = {}, None
    for line in open(os.path.join(ROOT, "robots", robot + ".joint_limits.yaml")):
        s = line.strip()
        if line.startswith("  ") and not line.startswith("    ") and s.endswith(":"):
            joint = s[:-1]
        elif s.startswith("max_acceleration:"):
            acc[joint] = float(s.split(":")[1])
    return acc


def group_joints(robot, group):
    """Joints of an SRDF group given as <joint> elements or a chain (in URDF order)."""
    t = ET.parse(os.path.join(ROOT, "robots", robot + ".srdf")).getroot()
    urdf = ET.parse(os.path.join(ROOT, "robots", robot + ".urdf")).getroot()
    movable = urdf_joints(robot)
    for g in t.findall("group"):
        if g.get("name") != group:
            continue
        names = [j.get("name") for j in g.findall("joint")]
        chain = g.find("chain")
        if chain is not None:
            parent = {j.find("child").get("link"): (j.get("name"), j.find("parent").get("link"))
                      for j in urdf.findall("joint")}
            link, names = chain.get("tip_link"), []
            while link != chain.get("base_link"):
                jn, link = parent[link]
                names.insert(0, jn)
        return [n for n in names if n in movable]
    raise KeyError(group)


def segment_time(a, b, vel, acc):
    a, b = np.asarray(a), np.asarray(b)
    length = float(np.linalg.norm(b - a))
    if length == 0.0:
        return 0.0
    path = ta.SplineInterpolator([0.0, length], np.vstack([a, b]), bc_type="natural")
    pc_vel = constraint.JointVelocityConstraint(np.vstack([-vel, vel]).T)
    pc_acc = constraint.JointAccelerationConstraint(np.vstack([-acc, acc]).T)
    grid = np.linspace(0.0, length, 2001)
    inst = algo.TOPPRA([pc_vel, pc_acc], path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    traj = inst.compute_trajectory(0.0, 0.0)
    if traj is None:
        raise RuntimeError("toppra failed")
    return float(traj.duration)


def case(name, robot, joints, lo, hi, vel, acc, rng, n):
    wps = [list(map(float, rng.uniform(lo, hi))) for _ in range(n)]
    t = sum(segment_time(wps[i], wps[i + 1], vel, acc) for i in range(n - 1))
    return {
        "name": name,
        "robot": robot,
        "joint_names": joints,
        "waypoints": wps,
        "max_velocity": list(map(float, vel)),
        "max_acceleration": list(map(float, acc)),
        "toppra_duration": t,
    }


def main():
    rng = np.random.default_rng(25)
    cases = []
    for robot, groups in [("armar", ["torso_right_arm", "right_arm"]),
                          ("justin", ["left_arm", "right_arm"])]:
        lim, acc = urdf_joints(robot), yaml_acc(robot)
        for g in groups:
            joints = group_joints(robot, g)
            lo = np.array([lim[j][0] for j in joints])
            hi = np.array([lim[j][1] for j in joints])
            vel = np.array([lim[j][2] for j in joints])
            a = np.array([acc[j] for j in joints])
            for k, n in enumerate([2, 6, 12]):
                cases.append(case(f"{robot}/{g}/{k}", robot, joints, lo, hi, vel, a, rng, n))
    # Panda-like 7-DoF (libfranka's limits: rad/s, rad/s^2).
    pvel = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
    pacc = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
    plo = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
    phi = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
    pj = [f"panda_joint{i}" for i in range(1, 8)]
    for k, n in enumerate([2, 10, 30]):
        cases.append(case(f"panda_like/{k}", None, pj, plo, phi, pvel, pacc, rng, n))
    out = {
        "generator": "tests/data/timing/make_toppra_fixture.py",
        "toppra_version": importlib.metadata.version("toppra"),
        "cases": cases,
    }
    path = os.path.join(os.path.dirname(__file__), "toppra_fixture.json")
    with open(path, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    print(f"{len(cases)} cases -> {path}")


if __name__ == "__main__":
    main()
