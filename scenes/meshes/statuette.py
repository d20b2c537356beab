#!/usr/bin/env python3
"""Writes statuette.obj beside this file: a horse statuette for the pick-and-place task (paper 003
grasps a horse statuette of 1 334 triangles), joined from swept primitives.

Each part is a closed, outward-oriented surface; parts overlap (legs enter the body and the
plinth, the neck enters body and head), so the statuette is the union of its parts, which is how
manyhands reads a mesh of several closed components (src/geometry/solid.rs: winding number > 1/2).
Units are metres, z up, the plinth's bottom at z = 0, the head toward +x. Deterministic: no
randomness; run `python3 scenes/meshes/statuette.py` to regenerate.
"""
import math
import os

verts = []
faces = []


def add_part(vs, fs):
    """Adds one closed part, flipping it if its signed volume is negative."""
    base = len(verts)
    vol = 0.0
    for a, b, c in fs:
        pa, pb, pc = vs[a], vs[b], vs[c]
        vol += (pa[0] * (pb[1] * pc[2] - pb[2] * pc[1])
                - pa[1] * (pb[0] * pc[2] - pb[2] * pc[0])
                + pa[2] * (pb[0] * pc[1] - pb[1] * pc[0])) / 6.0
    verts.extend(vs)
    for a, b, c in fs:
        faces.append((base + a, base + c, base + b) if vol < 0 else (base + a, base + b, base + c))


def ellipsoid(c, r, slices, stacks):
    vs = [(c[0], c[1], c[2] + r[2])]
    for i in range(1, stacks):
        th = math.pi * i / stacks
        for j in range(slices):
            ph = 2 * math.pi * j / slices
            vs.append((c[0] + r[0] * math.sin(th) * math.cos(ph),
                       c[1] + r[1] * math.sin(th) * math.sin(ph),
                       c[2] + r[2] * math.cos(th)))
    vs.append((c[0], c[1], c[2] - r[2]))
    fs = []
    ring = lambda i, j: 1 + (i - 1) * slices + (j % slices)
    for j in range(slices):
        fs.append((0, ring(1, j), ring(1, j + 1)))
    for i in range(1, stacks - 1):
        for j in range(slices):
            a, b = ring(i, j), ring(i, j + 1)
            c2, d = ring(i + 1, j), ring(i + 1, j + 1)
            fs.append((a, c2, d))
            fs.append((a, d, b))
    last = len(vs) - 1
    for j in range(slices):
        fs.append((last, ring(stacks - 1, j + 1), ring(stacks - 1, j)))
    add_part(vs, fs)


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    n = math.sqrt(sum(x * x for x in a))
    return (a[0] / n, a[1] / n, a[2] / n)


def tube(points, radii, sides):
    """A tube swept along a polyline (one ring per point, radius per point), capped."""
    vs = []
    prev_u = None
    for k, p in enumerate(points):
        t = norm(sub(points[min(k + 1, len(points) - 1)], points[max(k - 1, 0)]))
        if prev_u is None:
            u = norm(cross(t, (0, 0, 1) if abs(t[2]) < 0.9 else (1, 0, 0)))
        else:
            # Parallel transport: the previous ring's axis projected onto this ring's plane.
            d = sum(prev_u[i] * t[i] for i in range(3))
            u = norm(tuple(prev_u[i] - d * t[i] for i in range(3)))
        prev_u = u
        v = cross(t, u)
        for j in range(sides):
            a = 2 * math.pi * j / sides
            r = radii[k]
            vs.append(tuple(p[i] + r * (math.cos(a) * u[i] + math.sin(a) * v[i]) for i in range(3)))
    fs = []
    n = len(points)
    for k in range(n - 1):
        for j in range(sides):
            a, b = k * sides + j, k * sides + (j + 1) % sides
            c, d = a + sides, b + sides
            fs.append((a, b, d))
            fs.append((a, d, c))
    # Caps: a centre vertex each.
    c0 = len(vs)
    vs.append(points[0])
    c1 = len(vs)
    vs.append(points[-1])
    for j in range(sides):
        fs.append((c0, (j + 1) % sides, j))
        fs.append((c1, (n - 1) * sides + j, (n - 1) * sides + (j + 1) % sides))
    add_part(vs, fs)


def box(lo, hi):
    vs = [(lo[0] if i & 1 == 0 else hi[0], lo[1] if i & 2 == 0 else hi[1],
           lo[2] if i & 4 == 0 else hi[2]) for i in range(8)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    fs = []
    for a, b, c, d in quads:
        fs.append((a, b, c))
        fs.append((a, c, d))
    add_part(vs, fs)


# Plinth.
box((-0.14, -0.055, 0.0), (0.15, 0.055, 0.02))
# Body.
ellipsoid((0.0, 0.0, 0.19), (0.105, 0.048, 0.052), 18, 12)
# Legs: slightly bent tubes from the plinth into the body, knees forward on the front legs.
for x, knee in ((0.07, 0.012), (-0.07, -0.010)):
    for y in (-0.031, 0.031):
        tube([(x, y, 0.012), (x + knee * 0.3, y, 0.05), (x + knee, y, 0.09), (x + knee * 0.5, y, 0.13),
              (x * 0.9, y * 0.9, 0.185)], [0.012, 0.011, 0.013, 0.014, 0.017], 10)
# Neck and head.
tube([(0.075, 0.0, 0.2), (0.105, 0.0, 0.245), (0.13, 0.0, 0.29), (0.145, 0.0, 0.315)],
     [0.034, 0.03, 0.025, 0.022], 14)
ellipsoid((0.175, 0.0, 0.305), (0.05, 0.021, 0.024), 14, 9)
# Ears.
for y in (-0.011, 0.011):
    tube([(0.148, y, 0.325), (0.146, y, 0.345), (0.143, y, 0.358)], [0.007, 0.005, 0.0015], 6)
# Tail: swept down and back.
tube([(-0.095, 0.0, 0.2), (-0.125, 0.0, 0.19), (-0.145, 0.0, 0.16), (-0.152, 0.0, 0.12),
      (-0.148, 0.0, 0.08), (-0.14, 0.0, 0.05)], [0.012, 0.011, 0.01, 0.009, 0.008, 0.006], 8)

out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "statuette.obj")
with open(out, "w") as f:
    f.write("# Horse statuette for manyhands' pick-and-place scene (paper 003), written by statuette.py.\n")
    f.write(f"# {len(verts)} vertices, {len(faces)} triangles; closed parts joined by overlap; metres, z up.\n")
    for v in verts:
        f.write("v %.6f %.6f %.6f\n" % v)
    for a, b, c in faces:
        f.write(f"f {a + 1} {b + 1} {c + 1}\n")
print(f"{out}: {len(verts)} vertices, {len(faces)} triangles")
