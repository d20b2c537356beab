#!/usr/bin/env python3
"""Writes arm6.urdf and arm6.srdf beside this script: a 6-DoF arm of this project's own.

A UR5-like serial arm (shoulder pan/lift, elbow, three wrist joints; the published UR5
Denavit-Hartenberg lengths d1 = 0.089159, a2 = 0.425, a3 = 0.39225, d4 = 0.10915, d5 = 0.09465,
d6 = 0.0823) on a pedestal, with a two-finger gripper. Its collision model is spheres generated
here along each link's segment (radius per link, spacing 0.8 x radius), not a spherization of a
vendor's meshes. Used to measure that a robot the planners were never tuned on plans as fast
as the Panda (`manyhands data problems` + `manyhands bench mbm`, issue 28). Run it again after
changing it; tests read the two files, not this script.
"""
import math
from pathlib import Path

D1, A2, A3, D4, D5, D6 = 0.089159, 0.425, 0.39225, 0.10915, 0.09465, 0.0823
PI = math.pi
# (name, parent, child, xyz, rpy, axis, lower, upper, velocity)
JOINTS = [
    ("shoulder_pan", "base", "shoulder", f"0 0 {D1}", "0 0 0", "0 0 1", -PI, PI, 3.15),
    ("shoulder_lift", "shoulder", "upper_arm", "0 0.13585 0", f"0 {PI / 2} 0", "0 1 0", -PI, PI, 3.15),
    ("elbow", "upper_arm", "forearm", f"0 -0.1197 {A2}", "0 0 0", "0 1 0", -PI, PI, 3.15),
    ("wrist_1", "forearm", "wrist_1_link", f"0 0 {A3}", f"0 {PI / 2} 0", "0 1 0", -PI, PI, 3.2),
    ("wrist_2", "wrist_1_link", "wrist_2_link", f"0 {D4 - 0.13585 + 0.1197} 0", "0 0 0", "0 0 1", -PI, PI, 3.2),
    ("wrist_3", "wrist_2_link", "wrist_3_link", f"0 0 {D5}", "0 0 0", "0 1 0", -PI, PI, 3.2),
]


def chain(a, b, r):
    """Spheres of radius r along the segment a-b, centres at most 0.8 r apart."""
    d = [b[i] - a[i] for i in range(3)]
    length = math.sqrt(sum(x * x for x in d))
    n = max(1, math.ceil(length / (0.8 * r))) + 1
    return [tuple(a[i] + d[i] * k / (n - 1) for i in range(3)) + (r,) for k in range(n)] if length > 0 else [tuple(a) + (r,)]


SPHERES = {
    "pedestal": chain((0, 0, -0.30), (0, 0, -0.05), 0.09),
    "base": chain((0, 0, 0.0), (0, 0, 0.06), 0.075),
    "shoulder": chain((0, 0, 0), (0, 0.12, 0), 0.07),
    "upper_arm": chain((0, 0, 0), (0, 0, A2), 0.06),
    "forearm": chain((0, 0, 0.0), (0, 0, A3), 0.05),
    "wrist_1_link": chain((0, 0.0, 0), (0, 0.10, 0), 0.045),
    "wrist_2_link": chain((0, 0, 0), (0, 0, 0.09), 0.045),
    "wrist_3_link": chain((0, 0, 0), (0, 0.06, 0), 0.04),
    "gripper": chain((0, 0.0, 0), (0, 0.06, 0), 0.035) + [(0.03, 0.10, 0, 0.015), (-0.03, 0.10, 0, 0.015)],
}


def spheres(items, indent="    "):
    return "".join(
        f'{indent}<collision><origin xyz="{x:.5f} {y:.5f} {z:.5f}" rpy="0 0 0"/>'
        f'<geometry><sphere radius="{r}"/></geometry></collision>\n'
        for x, y, z, r in items
    )


def link(name):
    return f'  <link name="{name}">\n{spheres(SPHERES.get(name, []))}  </link>\n'


def urdf():
    out = ['<?xml version="1.0"?>\n<!-- Written by tests/robots/arm6.py. -->\n',
           '<robot name="arm6">\n', '  <link name="world"/>\n', link("pedestal"),
           '  <joint name="pedestal_fixed" type="fixed"><parent link="world"/><child link="pedestal"/>'
           '<origin xyz="0 0 0.3" rpy="0 0 0"/></joint>\n', link("base"),
           '  <joint name="base_fixed" type="fixed"><parent link="pedestal"/><child link="base"/>'
           '<origin xyz="0 0 0" rpy="0 0 0"/></joint>\n']
    for name, parent, child, xyz, rpy, axis, lo, hi, vel in JOINTS:
        out.append(link(child))
        out.append(
            f'  <joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>'
            f'<limit lower="{lo:.5f}" upper="{hi:.5f}" effort="150" velocity="{vel}"/></joint>\n'
        )
    out.append(link("gripper"))
    out.append(f'  <joint name="gripper_fixed" type="fixed"><parent link="wrist_3_link"/><child link="gripper"/>'
               f'<origin xyz="0 {D6} 0" rpy="0 0 0"/></joint>\n')
    out.append('  <link name="tcp"/>\n')
    out.append('  <joint name="tcp_fixed" type="fixed"><parent link="gripper"/><child link="tcp"/>'
               '<origin xyz="0 0.11 0" rpy="0 0 0"/></joint>\n')
    out.append("</robot>\n")
    return "".join(out)


def srdf():
    links = ["pedestal", "base", "shoulder", "upper_arm", "forearm", "wrist_1_link", "wrist_2_link", "wrist_3_link", "gripper"]
    out = ['<?xml version="1.0"?>\n<!-- Written by tests/robots/arm6.py. -->\n', '<robot name="arm6">\n',
           '  <group name="arm"><chain base_link="base" tip_link="tcp"/></group>\n',
           '  <group_state name="home" group="arm"><joint name="shoulder_pan" value="0"/>'
           '<joint name="shoulder_lift" value="-1.57"/><joint name="elbow" value="1.57"/>'
           '<joint name="wrist_1" value="-1.57"/><joint name="wrist_2" value="-1.57"/><joint name="wrist_3" value="0"/></group_state>\n',
           '  <end_effector name="gripper" parent_link="tcp" group="arm"/>\n']
    for a, b in zip(links, links[1:]):
        out.append(f'  <disable_collisions link1="{a}" link2="{b}" reason="Adjacent"/>\n')
    # Wrist links sit within a few centimetres of each other (as in every 6-DoF arm's SRDF).
    for a, b in [("forearm", "wrist_2_link"), ("wrist_1_link", "wrist_3_link"), ("wrist_1_link", "gripper"),
                 ("pedestal", "shoulder"), ("wrist_2_link", "gripper")]:
        out.append(f'  <disable_collisions link1="{a}" link2="{b}" reason="Never"/>\n')
    out.append("</robot>\n")
    return "".join(out)


here = Path(__file__).resolve().parent
(here / "arm6.urdf").write_text(urdf())
(here / "arm6.srdf").write_text(srdf())
