#!/usr/bin/env python3
"""Writes the generality suite's arms as URDF + SRDF with primitive collision geometry
(cylinders along each link, boxes for bases and grippers), from public kinematic parameters:

- ur5like:  6-DoF, the published UR5 Denavit-Hartenberg lengths (d1 0.089159, a2 0.425,
            a3 0.39225, d4 0.10915, d5 0.09465, d6 0.0823) on a pedestal, two-finger gripper;
- xarm7like: 7-DoF with offset elbow and wrist, the joint origins of UFACTORY's published xArm7
            description (d1 0.267, d3 0.293, a3 0.0525, a4 0.0775, d5 0.3425, a6 0.076, d7 0.097);
- fetchlike: 8-DoF mobile manipulator, a prismatic torso lift (0-0.386 m) and a 7-DoF arm with the
            link offsets of Fetch Robotics' published description (base fixed: the arm is planned);
- the dual-arm torso is not written here: it is robots/armar.urdf (its arms planned), see make.sh.

`make.sh` spherizes these with `manyhands robot spherize` and poses their problems with
`manyhands data problems`. Written files are committed; run make.sh again after changing this.
"""
import math
import sys
from pathlib import Path

PI = math.pi


def rpy_z_to(d):
    """rpy of a rotation taking +z to the direction d (roll 0)."""
    n = math.sqrt(sum(x * x for x in d))
    pitch = math.acos(max(-1.0, min(1.0, d[2] / n)))
    yaw = math.atan2(d[1], d[0])
    return (0.0, pitch, yaw)


def f(v):
    return " ".join(f"{x:.6f}" for x in v)


def cyl(a, b, r):
    """A cylinder of radius r whose axis joins a and b (link frame), plus r at both ends."""
    d = [b[i] - a[i] for i in range(3)]
    length = math.sqrt(sum(x * x for x in d))
    if length < 1e-9:
        return sphere(a, r)
    mid = [(a[i] + b[i]) / 2 for i in range(3)]
    return (f'    <collision><origin xyz="{f(mid)}" rpy="{f(rpy_z_to(d))}"/>'
            f'<geometry><cylinder radius="{r}" length="{length:.6f}"/></geometry></collision>\n')


def sphere(c, r):
    return (f'    <collision><origin xyz="{f(c)}" rpy="0 0 0"/>'
            f'<geometry><sphere radius="{r}"/></geometry></collision>\n')


def box(c, size, rpy=(0, 0, 0)):
    return (f'    <collision><origin xyz="{f(c)}" rpy="{f(rpy)}"/>'
            f'<geometry><box size="{f(size)}"/></geometry></collision>\n')


class Robot:
    def __init__(self, name, doc):
        self.name, self.doc = name, doc
        self.links, self.joints, self.chain = [], [], []

    def link(self, name, geometry=""):
        self.links.append(f'  <link name="{name}">\n{geometry}  </link>\n' if geometry else f'  <link name="{name}"/>\n')

    def joint(self, name, kind, parent, child, xyz, rpy=(0, 0, 0), axis=None, lo=None, hi=None):
        s = (f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
             f'<origin xyz="{f(xyz)}" rpy="{f(rpy)}"/>')
        if axis is not None:
            s += f'<axis xyz="{f(axis)}"/><limit lower="{lo:.6f}" upper="{hi:.6f}" effort="100" velocity="2"/>'
        self.joints.append(s + "</joint>\n")

    def urdf(self):
        return ('<?xml version="1.0"?>\n<!-- Written by benchmarks/generality/make_robots.py: '
                + self.doc + ' -->\n' + f'<robot name="{self.name}">\n'
                + "".join(self.links) + "".join(self.joints) + "</robot>\n")

    def srdf(self, group, base, tip, chain_links, extra_never=()):
        """Adjacent pairs along the chain and links two apart (they touch at the joint between
        them in most configurations, as in every vendor SRDF), plus `extra_never`."""
        out = ['<?xml version="1.0"?>\n<!-- Written by benchmarks/generality/make_robots.py. -->\n',
               f'<robot name="{self.name}">\n',
               f'  <group name="{group}"><chain base_link="{base}" tip_link="{tip}"/></group>\n',
               f'  <end_effector name="hand" parent_link="{tip}" group="{group}"/>\n']
        pairs = list(zip(chain_links, chain_links[1:])) + list(zip(chain_links, chain_links[2:]))
        for a, b in pairs + list(extra_never):
            out.append(f'  <disable_collisions link1="{a}" link2="{b}" reason="Adjacent"/>\n')
        out.append("</robot>\n")
        return "".join(out)


def gripper(r, parent, at, along):
    """A two-finger parallel gripper at `at` of `parent`, its fingers along the unit axis
    `along` (x, y or z index), and a tcp between the finger tips."""
    e = [0.0, 0.0, 0.0]
    e[along] = 1.0
    side = (along + 1) % 3 if along != 2 else 0
    palm_len, finger_len = 0.06, 0.05
    size_palm = [0.05, 0.05, 0.05]
    size_palm[side] = 0.16
    size_palm[along] = palm_len
    c_palm = [e[i] * palm_len / 2 for i in range(3)]
    fingers = ""
    for s in (-1, 1):
        c = [e[i] * (palm_len + finger_len / 2) for i in range(3)]
        c[side] = s * 0.065
        size = [0.02, 0.02, 0.02]
        size[along] = finger_len
        fingers += box(c, size)
    r.link("gripper", box(c_palm, size_palm) + fingers)
    r.joint("gripper_fixed", "fixed", parent, "gripper", at)
    r.link("tcp")
    r.joint("tcp_fixed", "fixed", "gripper", "tcp", [e[i] * (palm_len + finger_len - 0.01) for i in range(3)])


def ur5like():
    d1, a2, a3, d4, d5, d6 = 0.089159, 0.425, 0.39225, 0.10915, 0.09465, 0.0823
    r = Robot("ur5like", "a UR5-like 6-DoF arm (published UR5 DH lengths) with a two-finger gripper")
    r.link("world")
    r.link("pedestal", cyl([0, 0, -0.3], [0, 0, -0.02], 0.09))
    r.joint("pedestal_fixed", "fixed", "world", "pedestal", [0, 0, 0.3])
    r.link("base", cyl([0, 0, 0], [0, 0, 0.07], 0.075))
    r.joint("base_fixed", "fixed", "pedestal", "base", [0, 0, 0])
    y1, y2 = 0.13585, -0.1197
    links = [
        ("shoulder_pan", "base", "shoulder", [0, 0, d1], (0, 0, 0), [0, 0, 1], cyl([0, 0, -0.04], [0, 0, 0.06], 0.06) + cyl([0, 0, 0], [0, y1, 0], 0.06)),
        ("shoulder_lift", "shoulder", "upper_arm", [0, y1, 0], (0, PI / 2, 0), [0, 1, 0], cyl([0, 0, 0], [0, 0, a2], 0.055)),
        ("elbow", "upper_arm", "forearm", [0, y2, a2], (0, 0, 0), [0, 1, 0], cyl([0, 0, 0], [0, 0, a3], 0.045)),
        ("wrist_1", "forearm", "wrist_1_link", [0, 0, a3], (0, PI / 2, 0), [0, 1, 0], cyl([0, 0, 0], [0, d4 - y1 - y2, 0], 0.04)),
        ("wrist_2", "wrist_1_link", "wrist_2_link", [0, d4 - y1 - y2, 0], (0, 0, 0), [0, 0, 1], cyl([0, 0, 0], [0, 0, d5], 0.04)),
        ("wrist_3", "wrist_2_link", "wrist_3_link", [0, 0, d5], (0, 0, 0), [0, 1, 0], cyl([0, 0, 0], [0, d6, 0], 0.038)),
    ]
    for name, parent, child, xyz, rpy, axis, geom in links:
        r.link(child, geom)
        r.joint(name, "revolute", parent, child, xyz, rpy, axis, -PI, PI)
    gripper(r, "wrist_3_link", [0, d6, 0], 1)
    chain = ["pedestal", "base", "shoulder", "upper_arm", "forearm", "wrist_1_link", "wrist_2_link", "wrist_3_link", "gripper"]
    return r, r.srdf("arm", "base", "tcp", chain, [("wrist_1_link", "gripper")])


def xarm7like():
    r = Robot("xarm7like", "an xArm7-like 7-DoF arm with offset elbow and wrist (UFACTORY's published joint origins)")
    r.link("world")
    r.link("base", cyl([0, 0, 0], [0, 0, 0.12], 0.075))
    r.joint("base_fixed", "fixed", "world", "base", [0, 0, 0])
    # (joint, parent, child, xyz, rpy, lower, upper, geometry in the child frame), axes all z.
    spec = [
        ("joint1", "base", "link1", [0, 0, 0.267], (0, 0, 0), -PI, PI, cyl([0, 0, -0.14], [0, 0, 0.02], 0.06)),
        ("joint2", "link1", "link2", [0, 0, 0], (-PI / 2, 0, 0), -2.059, 2.0944, cyl([0, 0, 0], [0, -0.293, 0], 0.055)),
        ("joint3", "link2", "link3", [0, -0.293, 0], (PI / 2, 0, 0), -PI, PI, cyl([0, 0, -0.05], [0.0525, 0, 0], 0.05)),
        ("joint4", "link3", "link4", [0.0525, 0, 0], (PI / 2, 0, 0), -0.19198, 3.927, cyl([0, 0, 0], [0.0775, -0.3425, 0], 0.05)),
        ("joint5", "link4", "link5", [0.0775, -0.3425, 0], (PI / 2, 0, 0), -PI, PI, cyl([0, 0, -0.06], [0, 0, 0.02], 0.045)),
        ("joint6", "link5", "link6", [0, 0, 0], (PI / 2, 0, 0), -1.69297, PI, cyl([0, 0, 0], [0.076, 0.097, 0], 0.045)),
        ("joint7", "link6", "link7", [0.076, 0.097, 0], (-PI / 2, 0, 0), -PI, PI, cyl([0, 0, -0.02], [0, 0, 0.02], 0.04)),
    ]
    for name, parent, child, xyz, rpy, lo, hi, geom in spec:
        r.link(child, geom)
        r.joint(name, "revolute", parent, child, xyz, rpy, [0, 0, 1], lo, hi)
    gripper(r, "link7", [0, 0, 0.02], 2)
    chain = ["base", "link1", "link2", "link3", "link4", "link5", "link6", "link7", "gripper"]
    return r, r.srdf("arm", "base", "tcp", chain, [("link5", "link7"), ("link5", "gripper")])


def fetchlike():
    r = Robot("fetchlike", "a Fetch-like mobile manipulator: torso lift and 7-DoF arm (Fetch Robotics' published offsets)")
    r.link("base_link", sphere([0, 0, 0.05], 0.3))
    r.link("torso_fixed_link", cyl([-0.086875, 0, 0.3], [-0.086875, 0, 0.7], 0.13))
    r.joint("torso_fixed_joint", "fixed", "base_link", "torso_fixed_link", [0, 0, 0])
    r.link("torso_lift_link", cyl([-0.01, 0, 0.0], [-0.01, 0, 0.7], 0.12) + sphere([0.02, 0, 0.86], 0.14))
    r.joint("torso_lift_joint", "prismatic", "base_link", "torso_lift_link", [-0.086875, 0, 0.37743], (0, 0, 0), [0, 0, 1], 0.0, 0.386)
    spec = [
        ("shoulder_pan_joint", "torso_lift_link", "shoulder_pan_link", [0.119525, 0, 0.34858], [0, 0, 1], -1.6056, 1.6056, cyl([0, 0, -0.02], [0, 0, 0.07], 0.07)),
        ("shoulder_lift_joint", "shoulder_pan_link", "shoulder_lift_link", [0.117, 0, 0.06], [0, 1, 0], -1.221, 1.518, cyl([0, 0, 0], [0.219, 0, 0], 0.065)),
        ("upperarm_roll_joint", "shoulder_lift_link", "upperarm_roll_link", [0.219, 0, 0], [1, 0, 0], -PI, PI, cyl([0, 0, 0], [0.133, 0, 0], 0.06)),
        ("elbow_flex_joint", "upperarm_roll_link", "elbow_flex_link", [0.133, 0, 0], [0, 1, 0], -2.251, 2.251, cyl([0, 0, 0], [0.197, 0, 0], 0.06)),
        ("forearm_roll_joint", "elbow_flex_link", "forearm_roll_link", [0.197, 0, 0], [1, 0, 0], -PI, PI, cyl([0, 0, 0], [0.1245, 0, 0], 0.055)),
        ("wrist_flex_joint", "forearm_roll_link", "wrist_flex_link", [0.1245, 0, 0], [0, 1, 0], -2.16, 2.16, cyl([0, 0, 0], [0.1385, 0, 0], 0.055)),
        ("wrist_roll_joint", "wrist_flex_link", "wrist_roll_link", [0.1385, 0, 0], [1, 0, 0], -PI, PI, cyl([0, 0, 0], [0.06, 0, 0], 0.05)),
    ]
    for name, parent, child, xyz, axis, lo, hi, geom in spec:
        r.link(child, geom)
        r.joint(name, "revolute", parent, child, xyz, (0, 0, 0), axis, lo, hi)
    gripper(r, "wrist_roll_link", [0.10645, 0, 0], 0)
    chain = ["torso_lift_link", "shoulder_pan_link", "shoulder_lift_link", "upperarm_roll_link", "elbow_flex_link",
             "forearm_roll_link", "wrist_flex_link", "wrist_roll_link", "gripper"]
    extra = [("base_link", "torso_lift_link"), ("base_link", "torso_fixed_link"), ("torso_fixed_link", "torso_lift_link"),
             ("wrist_flex_link", "gripper"), ("torso_fixed_link", "shoulder_pan_link")]
    return r, r.srdf("arm_with_torso", "base_link", "tcp", chain, extra)


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent / "primitive"
    out.mkdir(parents=True, exist_ok=True)
    for make in (ur5like, xarm7like, fetchlike):
        r, srdf = make()
        (out / f"{r.name}.urdf").write_text(r.urdf())
        (out / f"{r.name}.srdf").write_text(srdf)


main()
