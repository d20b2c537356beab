#!/usr/bin/env python3
"""Writes twin_arms.urdf and twin_arms.srdf beside this script: the test robot of the suite.

Two 7-DoF arms with the kinematics of the Franka Panda (joint origins and limits as published in
franka_description, including the URDF's truncated pi/2 in the joint rpy), mounted upright
0.6 m apart on a fixed torso; every link's collision geometry is a few spheres placed by hand
here (not the benchmark's spherization). Tests use it wherever they need "some outside robot"
made of spheres: FK paths, Jacobians and numeric IK, the exact and the sphere checkers, planning.
Run it again after changing it; the tests read the two files, not this script.
"""
from pathlib import Path

HALF_PI = "1.57079632679"  # as franka_description writes it
# (name, parent suffix, xyz, rpy, lower, upper)
JOINTS = [
    ("joint1", "link0", "0 0 0.333", "0 0 0", -2.8973, 2.8973),
    ("joint2", "link1", "0 0 0", f"-{HALF_PI} 0 0", -1.7628, 1.7628),
    ("joint3", "link2", "0 -0.316 0", f"{HALF_PI} 0 0", -2.8973, 2.8973),
    ("joint4", "link3", "0.0825 0 0", f"{HALF_PI} 0 0", -3.0718, -0.0698),
    ("joint5", "link4", "-0.0825 0.384 0", f"-{HALF_PI} 0 0", -2.8973, 2.8973),
    ("joint6", "link5", "0 0 0", f"{HALF_PI} 0 0", -0.0175, 3.7525),
    ("joint7", "link6", "0.088 0 0", f"{HALF_PI} 0 0", -2.8973, 2.8973),
]
# Spheres (x, y, z, radius) in each link's frame.
SPHERES = {
    "link0": [(0, 0, 0.06, 0.08), (-0.06, 0, 0.12, 0.06), (0, 0, 0.2, 0.07)],
    "link1": [(0, 0, -0.2, 0.07), (0, -0.02, -0.11, 0.065), (0, -0.04, -0.03, 0.06)],
    "link2": [(0, 0, 0.03, 0.06), (0, -0.07, 0.0, 0.06), (0, -0.14, 0.0, 0.06)],
    "link3": [(0, 0, -0.12, 0.06), (0.04, 0.02, -0.05, 0.055), (0.08, 0.04, 0.0, 0.055)],
    "link4": [(0, 0, 0.0, 0.06), (-0.06, 0.06, 0.0, 0.055), (-0.08, 0.12, 0.0, 0.055)],
    "link5": [(0, 0.04, -0.22, 0.06), (0, 0.06, -0.14, 0.045), (0, 0.02, -0.05, 0.05), (0, 0, 0, 0.055)],
    "link6": [(0, 0, 0, 0.05), (0.05, 0.01, 0, 0.05), (0.09, 0.02, 0, 0.045)],
    "link7": [(0, 0, 0.06, 0.05), (0.03, 0.03, 0.08, 0.035), (0.04, 0.06, 0.085, 0.025)],
    # The hand is four rigidly joined links (as the Panda's hand and fingers are in the
    # benchmark), so that one node carries several bodies.
    "hand": [(0, -0.025, 0.02, 0.035), (0, 0.025, 0.02, 0.035)],
    "palm": [(0, -0.07, 0.02, 0.03), (0, 0.07, 0.02, 0.03)],
    "leftfinger": [(0, 0.035, 0.08, 0.015)],
    "rightfinger": [(0, -0.035, 0.08, 0.015)],
}
TORSO = [(0, 0, 0.1, 0.12), (0, 0, 0.25, 0.1), (0, 0.15, 0.32, 0.07), (0, -0.15, 0.32, 0.07)]
MOUNTS = {"left": "0 0.3 0.4", "right": "0 -0.3 0.4"}
HAND_PARTS = ["palm", "leftfinger", "rightfinger"]
READY = [0, -0.785, 0, -2.356, 0, 1.571, 0.785]


def spheres(items, indent="    "):
    return "".join(
        f'{indent}<collision><origin xyz="{x} {y} {z}" rpy="0 0 0"/>'
        f'<geometry><sphere radius="{r}"/></geometry></collision>\n'
        for x, y, z, r in items
    )


def link(name, items):
    return f'  <link name="{name}">\n{spheres(items)}  </link>\n'


def fixed(name, parent, child, xyz="0 0 0", rpy="0 0 0"):
    return (
        f'  <joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/></joint>\n'
    )


def urdf():
    out = ['<?xml version="1.0"?>\n<!-- Written by tests/robots/twin_arms.py. -->\n',
           '<robot name="twin_arms">\n', '  <link name="world"/>\n', link("torso", TORSO),
           fixed("torso_fixed", "world", "torso")]
    for side, mount in MOUNTS.items():
        p = f"{side}_"
        out.append(link(p + "link0", SPHERES["link0"]))
        out.append(fixed(p + "mount", "torso", p + "link0", mount))
        for k, (j, parent, xyz, rpy, lo, hi) in enumerate(JOINTS):
            child = f"{p}link{k + 1}"
            out.append(link(child, SPHERES[f"link{k + 1}"]))
            out.append(
                f'  <joint name="{p}{j}" type="revolute"><parent link="{p}{parent}"/>'
                f'<child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/>'
                f'<limit lower="{lo}" upper="{hi}" effort="87" velocity="2.175"/></joint>\n'
            )
        out.append(f'  <link name="{p}link8"/>\n')
        out.append(fixed(p + "joint8", p + "link7", p + "link8", "0 0 0.107"))
        out.append(link(p + "hand", SPHERES["hand"]))
        out.append(fixed(p + "hand_joint", p + "link8", p + "hand", rpy="0 0 -0.785398163397"))
        for part in HAND_PARTS:
            out.append(link(p + part, SPHERES[part]))
            out.append(fixed(f"{p}{part}_joint", p + "hand", p + part))
        out.append(f'  <link name="{p}tcp"/>\n')
        out.append(fixed(p + "tcp_joint", p + "hand", p + "tcp", "0 0 0.1034"))
    out.append("</robot>\n")
    return "".join(out)


def srdf():
    out = ['<?xml version="1.0"?>\n<!-- Written by tests/robots/twin_arms.py. -->\n',
           '<robot name="twin_arms">\n']
    for side in MOUNTS:
        out.append(f'  <group name="{side}_arm"><chain base_link="{side}_link0" tip_link="{side}_tcp"/></group>\n')
    out.append('  <group name="both_arms"><group name="left_arm"/><group name="right_arm"/></group>\n')
    out.append('  <group_state name="ready" group="both_arms">\n')
    for side in MOUNTS:
        for k, v in enumerate(READY):
            out.append(f'    <joint name="{side}_joint{k + 1}" value="{v}"/>\n')
    out.append("  </group_state>\n")
    for side in MOUNTS:
        out.append(f'  <end_effector name="{side}_hand" parent_link="{side}_tcp" group="{side}_arm"/>\n')
    chain = ["link0", "link1", "link2", "link3", "link4", "link5", "link6", "link7", "hand"]
    for side in MOUNTS:
        p = f"{side}_"
        out.append(f'  <disable_collisions link1="torso" link2="{p}link0" reason="Adjacent"/>\n')
        out.append(f'  <disable_collisions link1="torso" link2="{p}link1" reason="Never"/>\n')
        for a, b in zip(chain, chain[1:]):
            out.append(f'  <disable_collisions link1="{p}{a}" link2="{p}{b}" reason="Adjacent"/>\n')
        hand = ["hand"] + HAND_PARTS
        for i, a in enumerate(hand):
            for b in hand[i + 1:]:
                out.append(f'  <disable_collisions link1="{p}{a}" link2="{p}{b}" reason="Adjacent"/>\n')
            for b in ["link5", "link6", "link7"]:
                out.append(f'  <disable_collisions link1="{p}{a}" link2="{p}{b}" reason="Never"/>\n')
        # Two joints apart but always touching (the wrist cluster and the shoulder).
        for a, b in [("link0", "link2"), ("link1", "link3"), ("link5", "link7"),
                     ("link2", "link4")]:
            out.append(f'  <disable_collisions link1="{p}{a}" link2="{p}{b}" reason="Never"/>\n')
    out.append("</robot>\n")
    return "".join(out)


here = Path(__file__).resolve().parent
(here / "twin_arms.urdf").write_text(urdf())
(here / "twin_arms.srdf").write_text(srdf())
